"""`python -m magyro` is the `magyro` command."""
from magyro.cli import main

main()
