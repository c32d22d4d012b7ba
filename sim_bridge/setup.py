"""Install sim_bridge: the pybullet simulator, its ROS 2 bridge node, the runner and grader."""

from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'sim_bridge'
share = os.path.join('share', package_name)


def tree(source, destination):
    """Return data_files entries copying the folder ``source`` to ``destination`` as a tree."""
    return [(os.path.join(destination, os.path.relpath(folder, source)),
             [os.path.join(folder, name) for name in names])
            for folder, _, names in os.walk(source) if names]


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    # The HTML pages' jinja2 templates (sim_bridge.grading.html_report).
    package_data={f'{package_name}.grading': ['templates/*.html']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        (share, ['package.xml']),
        (os.path.join(share, 'launch'), glob('launch/*.launch.py')),
        (os.path.join(share, 'params'), glob('params/*.yaml') + glob('params/*.rviz')),
        # The worlds, models, shipped scenarios and example nodes: links to the workspace's
        # top-level folders (their source), so that the package built alone, a copy of its
        # folder, installs them too; sim_bridge.common.paths finds them in a checkout or here.
        *tree('worlds', os.path.join(share, 'worlds')),
        *tree('models', os.path.join(share, 'models')),
        *tree('scenarios', os.path.join(share, 'scenarios')),
        *tree('examples', os.path.join(share, 'examples')),
    ],
    install_requires=['setuptools', 'numpy>=1.26,<2', 'pybullet', 'mcap>=1.1', 'matplotlib',
                      'contourpy', 'PyYAML', 'trimesh', 'pycollada', 'shapely', 'pillow',
                      'imageio-ffmpeg', 'jinja2', 'pydantic>=2', 'rich', 'lxml', 'xacro',
                      'urdfdom-py'],
    extras_require={
        'test': [
            'pytest',
        ],
    },
    zip_safe=False,
    maintainer='Laser Lab Kit maintainers',
    maintainer_email='laser-lab@example.org',
    description='pybullet stand-in for Gazebo, ROS 2 bridge node, stepped runner and grader.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim_bridge = sim_bridge.ros.bridge:main',
            'lab_run = sim_bridge.commands.run:main',
            'lab_grade = sim_bridge.commands.grade:main',
            'lab_check = sim_bridge.commands.check:main',
            'lab_video = sim_bridge.commands.video:main',
            'teleop_keyboard = sim_bridge.ros.teleop:main',
            'send_cmd_vel = sim_bridge.ros.send_cmd_vel:main',
        ],
    },
)
