"""`python -m fogsf` is the `fogsf` command."""

import sys

from fogsf.cli.main import main

if __name__ == "__main__":
    sys.exit(main())
