"""``python -m skewpend`` runs the command-line tool."""

from .cli import main

main()
