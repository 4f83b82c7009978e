"""Measurements of sidar_torch: speed, speed against error, accuracy, exposure, memory.

Not part of the installed package. Run each from the repository root as
``python -m benchmarks.<name> --help``; ``benchmarks/README.md`` lists them with what they print.
"""
