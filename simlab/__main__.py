import sys

from simlab.cli import console_main

sys.exit(console_main())
