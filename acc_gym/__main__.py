"""``python -m acc_gym``: the ``acc-gym`` command line (:mod:`acc_gym.cli`)."""

import sys

from acc_gym.cli import main

if __name__ == "__main__":
    sys.exit(main())
