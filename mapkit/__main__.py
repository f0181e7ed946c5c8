"""``python -m mapkit`` runs the command-line tool."""

from mapkit.cli.main import main

main()
