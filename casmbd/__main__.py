"""``python -m casmbd`` runs the command-line interface."""

import sys

from casmbd.cli import main

sys.exit(main())
