"""`python -m psrt ...`: the same as the `psrt` console script."""
import sys

from psrt.cli import main

sys.exit(main())
