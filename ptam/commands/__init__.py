"""Implementations of the ``ptam`` subcommands (thin: parse, call the library, print)."""
