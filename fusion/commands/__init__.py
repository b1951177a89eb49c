"""Subcommands of the ``fusion`` command line, one module each.

Each module defines ``register(subparsers)``, which adds its parser and sets ``handler=run``
with ``run(args) -> int``.
"""
