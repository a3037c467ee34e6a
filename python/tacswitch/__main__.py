"""``python -m tacswitch`` runs the command line."""

import sys

from tacswitch.cli import main

sys.exit(main())
