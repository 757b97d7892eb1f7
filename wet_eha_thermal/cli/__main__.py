"""``python -m wet_eha_thermal.cli``: the ``wet-eha-thermal`` command."""

import sys

from . import main

if __name__ == '__main__':      # imported by a tool that walks the package, it does nothing
    sys.exit(main())
