"""Where the drive's object dictionary (EDS) lives, in a clone and in an installed package."""
from __future__ import annotations

from pathlib import Path

from planter_ros.shipped import shipped_file

EDS_NAME = 'planter_drive.eds'


def default_eds_path() -> Path:
    """config/planter_drive.eds of this clone, else of the installed share directory."""
    return shipped_file(EDS_NAME)
