"""`python -m kinetre.cli ...`: the same as the `kinetre` console script."""
import sys

from .main import main

sys.exit(main())
