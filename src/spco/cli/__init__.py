"""The ``spco`` command line (entry point ``spco.cli:main``): :mod:`spco.cli.main` holds the click
group, one module per command group beside it, and :mod:`spco.cli.errors` the error reporting."""

from spco.cli.data import inspect
from spco.cli.main import main

__all__ = ["inspect", "main"]
