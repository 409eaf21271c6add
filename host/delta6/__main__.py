import sys

from delta6.console import main

sys.exit(main())
