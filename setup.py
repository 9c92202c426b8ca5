"""ament_python package: installable with colcon on a ROS machine and with pip into a venv."""
from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'planter_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', [p for p in glob('config/*') if os.path.isfile(p)]),
        ('share/' + package_name + '/config/machines', glob('config/machines/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/systemd', glob('systemd/*')),
    ],
    # What the package needs at run time, with the oldest versions it is known to work with;
    # requirements.txt pins the exact versions the bootstrap and CI install.
    install_requires=[
        'setuptools',
        'ros-jazzy-rclpy[fastrtps]>=7.1.6',        # ROS 2 Jazzy from PyPI wheels
        'ros-jazzy-common-interfaces>=5.3.6',     # std/geometry/sensor/diagnostic msgs
        'numpy>=2.0',
        'scipy>=1.13',
        'PyYAML>=6.0',
        'python-can>=4.4',
        'canopen>=2.4',
        'mcap>=1.2',
        'zstandard>=0.22',
        'isal>=1.6',                              # the chunks' CRC-32, fast
        'rosbags>=0.10',
        'matplotlib>=3.8',
        'pyproj>=3.6',                            # geodesy of the as-planted map
        'dask[distributed]>=2024.8',              # planter analyze on a cluster
        'pyarrow>=15',                            # Parquet tables of a season
        'mpmath>=1.3',                            # planter bench's references
        'pyshp>=2.3',                             # Shapefile export
        'isoxml>=0.0.4',                          # ISO 11783-10 task data export
        'xsdata>=24.7',                           # isoxml's bindings (its date-time type)
        'cantools>=39.4',                         # ISOBUS speed messages from a DBC
    ],
    extras_require={'test': ['pytest>=8', 'hypothesis>=6.100', 'colcon-common-extensions',
                             'ruff>=0.6', 'pyogrio>=0.10', 'xmlschema>=3.0']},
    zip_safe=True,
    maintainer='planter_ros team',
    maintainer_email='planter@example.org',
    description='Design and drive the planting unit of a seedling transplanter.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'planter = planter_ros.cli.main:main',
            'design_node = planter_ros.nodes.entry:design_node',
            'sync_node = planter_ros.nodes.entry:sync_node',
            'monitor_node = planter_ros.nodes.entry:monitor_node',
            'ground_speed_node = planter_ros.nodes.entry:ground_speed_node',
        ],
    },
)
