"""Measurements of sidar_torch: speed, speed against error, accuracy, exposure, memory.

Not part of the installed package. Run each from the repository root as
``python -m benchmarks.<name> --help``; ``benchmarks/README.md`` lists them with what they print.
"""

from sidar_torch.render import render_in_this_process

# Benchmarks measure rendering in their own process's CPU time (``time.process_time``), so every sample
# they make renders here, not in a render process; their contexts compile cold (no disk cache), as before.
# ``first_minute`` measures the default (a render process) in fresh interpreters of its own.
render_in_this_process()
