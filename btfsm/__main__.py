"""``python -m btfsm``: the same command line as the ``btfsm`` script."""
import sys

from btfsm.cli import main

if __name__ == "__main__":
    sys.exit(main())
