"""The ``inscal`` command line: one module per subcommand (``inscal.cli.<name>``, each with
``register(app)``), assembled by :mod:`inscal.cli.app`.  No domain logic lives here: the
subcommands import the library inside their functions, so ``inscal --help`` starts fast."""

from inscal.cli.app import app, main

__all__ = ["app", "main"]
