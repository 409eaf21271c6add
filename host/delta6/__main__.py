import sys

from delta6.cli import main

sys.exit(main())
