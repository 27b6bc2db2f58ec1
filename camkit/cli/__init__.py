"""The ``camkit`` command line: parse arguments, call the public API, print."""
