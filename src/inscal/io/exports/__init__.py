"""Exports of inscal results into other tools' conventions (one module per kind of result)."""
