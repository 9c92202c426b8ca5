"""`python -m planter_ros.command --fd N --parent PID`: the command process (process.py)."""
import sys

from planter_ros.command.process import main

sys.exit(main())
