"""The ``dhlog`` command line: a thin layer over the library."""
