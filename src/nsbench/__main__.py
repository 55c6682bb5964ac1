"""``python -m nsbench`` runs the command line."""

import sys

from nsbench.cli import main

sys.exit(main())
