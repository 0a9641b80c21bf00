"""`python -m fogsf` is the `fogsf` command."""

import sys

from fogsf.trainer.cli import main

if __name__ == "__main__":
    sys.exit(main())
