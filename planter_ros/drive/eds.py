"""Where the drive's object dictionary (EDS) lives, in a clone and in an installed package."""
from __future__ import annotations

import sys
from pathlib import Path

EDS_NAME = 'planter_drive.eds'


def default_eds_path() -> Path:
    """config/planter_drive.eds of this clone, else of the installed share directory."""
    candidates = [Path(__file__).resolve().parents[2] / 'config' / EDS_NAME,
                  Path(sys.prefix) / 'share' / 'planter_ros' / 'config' / EDS_NAME]
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory('planter_ros')) / 'config' / EDS_NAME)
    except Exception:                     # not a ROS install, or the package is not indexed
        pass
    for path in candidates:
        if path.is_file():
            return path
    raise FileNotFoundError(f'{EDS_NAME} not found in: ' + ', '.join(str(p) for p in candidates))
