"""``python -m mjjoint``, the same as the ``mjjoint`` script."""
from .cli import main

raise SystemExit(main())
