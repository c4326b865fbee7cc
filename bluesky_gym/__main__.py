"""``python -m bluesky_gym``."""

import sys

from bluesky_gym.cli import main

sys.exit(main())
