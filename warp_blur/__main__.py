"""`python -m warp_blur ...` is the `warp-blur` command."""

import sys

from .tools.cli import main

sys.exit(main())
