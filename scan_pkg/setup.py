"""Install scan_pkg: the lab's scan-reading and driving nodes and their pure cores."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'scan_pkg'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/params', glob('params/*.yaml')),
    ],
    install_requires=['setuptools', 'numpy>=1.26,<2'],
    extras_require={
        'test': [
            'pytest',
        ],
    },
    zip_safe=True,
    maintainer='Laser Lab Kit maintainers',
    maintainer_email='laser-lab@example.org',
    description='Laser range finder lab nodes: scan reading, wanderbot and wall following.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'scan_ahead = scan_pkg.scan_ahead:main',
            'scan_around = scan_pkg.scan_around:main',
            'closest_obstacle = scan_pkg.closest_obstacle:main',
            'wanderbot = scan_pkg.wanderbot:main',
            'wall_follow = scan_pkg.wall_follow:main',
        ],
    },
)
