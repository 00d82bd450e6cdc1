"""The ``previewctl`` command line: one module per command."""
