"""ament_python package: installable with colcon on a ROS machine and with pip into a venv."""
from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'planter_ros'
_declared = {}
exec(open(os.path.join(os.path.dirname(os.path.abspath(__file__)), package_name,
                       'dependencies.py')).read(), _declared)
ROLES = _declared['ROLES']

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
        ('share/' + package_name + '/rosdep', glob('rosdep/*.yaml')),
    ],
    # What each role needs, declared once in planter_ros/dependencies.py (read here without
    # importing the package): the base install is what the nodes and the command process
    # import; the extras `analysis` and `dev`. requirements.txt pins every version.
    install_requires=ROLES['base'],
    extras_require={'analysis': ROLES['analysis'], 'dev': ROLES['dev']},
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
