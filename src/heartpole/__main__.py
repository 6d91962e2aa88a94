"""``python -m heartpole`` runs the ``heartpole`` command."""

import sys

from heartpole.cli import main

sys.exit(main())
