"""``python -m fuzzyservo`` runs the command line."""

import sys

from fuzzyservo.cli import main

sys.exit(main())
