"""``python -m seaway_lab.docs_reference reference [--check]``: the same as ``seaway docs``."""

from seaway_lab.docs_reference.cli import main

raise SystemExit(main())
