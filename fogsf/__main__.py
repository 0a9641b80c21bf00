"""`python -m fogsf` is the `fogsf` command."""

import sys

from fogsf.trainer.cli import main

sys.exit(main())
