"""``python -m mjjoint.cli``, the same as the ``mjjoint`` script."""
from . import main

raise SystemExit(main())
