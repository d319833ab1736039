"""``python -m bdft``: the same as the ``bdft`` command."""

import sys

from bdft import console

sys.exit(console())
