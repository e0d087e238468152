"""``python -m ottag_db`` runs the command line."""

from ottag_db.cli import main

if __name__ == "__main__":
    main()
