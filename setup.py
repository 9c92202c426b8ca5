"""ament_python package: installable with colcon on a ROS machine and with pip into a venv."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'planter_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='planter_ros team',
    maintainer_email='planter@example.org',
    description='Design and drive the planting unit of a seedling transplanter.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'planter = planter_ros.cli.main:main',
            'design_node = planter_ros.nodes.design_node:main',
            'sync_node = planter_ros.nodes.sync_node:main',
            'monitor_node = planter_ros.nodes.monitor_node:main',
        ],
    },
)
