"""``python -m spco`` runs the command line."""

from spco.cli import main

main()
