"""``python -m agents``: the ``scara-agents`` console script."""

from agents.cli import main

raise SystemExit(main())
