"""Thin shells over the library: the `doorloc` command line, the HTTP service and the batch runner."""
