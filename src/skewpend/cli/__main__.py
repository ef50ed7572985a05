"""``python -m skewpend.cli`` runs the command-line tool."""

from . import main

main()
