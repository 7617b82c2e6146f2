"""``python -m rbbench.cli``: the ``rbbench`` command."""

import sys

from rbbench.cli import main

sys.exit(main())
