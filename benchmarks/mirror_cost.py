"""Former command of ``python -m benchmarks.setting_cost --field mirrors`` (the cost of the painting's
reflections and refraction), kept while docs cite it: the same options and measurement."""

from .setting_cost import former_command

parse_args, main = former_command(["--field", "mirrors"])

if __name__ == "__main__":
    main()
