"""The package's version, in a module of its own so that any layer can import it (the package's
``__init__`` imports every layer)."""

__version__ = "0.1.0"
