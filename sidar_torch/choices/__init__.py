"""The floor under ``config``: the names both the configuration and the floors that implement them need,
as plain data and pure NumPy math (no GL, nothing of the package imported): the renderer's choices
(:mod:`.render`), the optional outputs' table (:mod:`.outputs`) and the lens models (:mod:`.lenses`)."""
