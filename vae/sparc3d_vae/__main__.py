"""`python -m sparc3d_vae ...`: the same commands as `sparc3d-vae`."""

import sys

from .cli import main

sys.exit(main())
