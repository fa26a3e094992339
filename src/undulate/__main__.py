"""``python -m undulate ARGS``: the ``undulate`` command line (:mod:`undulate.cli`)."""

from .cli import main

raise SystemExit(main())
