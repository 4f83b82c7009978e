"""Former command of ``python -m benchmarks.setting_cost --field opacities --samples 60`` (the cost of
``opacity_output``), kept while docs cite it: the same options and measurement."""

from .setting_cost import former_command

parse_args, main = former_command(["--field", "opacities", "--samples", "60"])

if __name__ == "__main__":
    main()
