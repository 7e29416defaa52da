"""``python -m feeler`` is the ``feeler`` command."""
import sys

from feeler.cli import main

sys.exit(main())
