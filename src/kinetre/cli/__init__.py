"""The `kinetre` command line: one module per command, each with `register(subparsers)` and its handler;
`common` holds what they share. `main` runs it (the console script and `python -m kinetre.cli`)."""
from .main import build_parser, main

__all__ = ["build_parser", "main"]
