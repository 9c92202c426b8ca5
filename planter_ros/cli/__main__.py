"""`python -m planter_ros.cli` = `planter`."""
import sys

from planter_ros.cli.main import main

sys.exit(main())
