"""``python -m previewctl``: the same as the ``previewctl`` command."""

from previewctl.cli.main import main

raise SystemExit(main())
