"""The command line run as a module: python -m with this package name."""

from crashstudy.cli.main import main

raise SystemExit(main())
