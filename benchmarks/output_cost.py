"""Former command of ``python -m benchmarks.setting_cost --field NAME`` for a drawn output
(``--output NAME``, default ``shadow_masks``), kept while docs cite it: the same options and measurement."""

from .setting_cost import former_command

parse_args, main = former_command(["--field", "shadow_masks"], renamed="--output")

if __name__ == "__main__":
    main()
