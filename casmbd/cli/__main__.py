"""``python -m casmbd.cli`` (as before the CLI became a package) runs the command-line interface."""

import sys

from casmbd.cli import main

sys.exit(main())
