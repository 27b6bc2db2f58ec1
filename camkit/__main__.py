"""``python -m camkit`` runs the command line."""

from camkit.cli.main import main

raise SystemExit(main())
