"""`python -m magyro.cli` is the `magyro` command."""
from magyro.cli import main

main()
