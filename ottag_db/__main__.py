"""``python -m ottag_db`` runs the command line."""

from .cli import main

main()
