"""``python -m vesicle_core.cli``: the ``vesicle`` command."""

import sys

from . import main

sys.exit(main())
