"""``python -m wet_eha_thermal.cli``: the ``wet-eha-thermal`` command."""

import sys

from . import main

sys.exit(main())
