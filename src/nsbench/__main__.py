"""``python -m nsbench`` runs the command line."""

from nsbench.cli import console

console()
