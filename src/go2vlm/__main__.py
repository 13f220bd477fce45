import sys

from go2vlm.cli.main import main

sys.exit(main())
