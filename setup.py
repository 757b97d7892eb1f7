"""Build script for the wet_eha_thermal ament_python package."""

from glob import glob

from setuptools import find_packages
from setuptools import setup

PACKAGE = 'wet_eha_thermal'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.py')),
        ('share/' + PACKAGE + '/layouts', glob('layouts/*.json')),
    ],
    # Runtime dependencies are declared in package.xml (rosdep, colcon) and
    # requirements.txt (the pip/venv path of scripts/dev), as ROS does.
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='wet-eha-thermal developers',
    maintainer_email='dev@example.com',
    description='Digital-twin thermal estimator for a wet electro-hydrostatic actuator.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'wet-eha-thermal = wet_eha_thermal.cli:main',
            'wet-eha-thermal-estimator = wet_eha_thermal.ros.estimator_node:main',
            'wet-eha-thermal-rig = wet_eha_thermal.ros.sim_rig_node:main',
            'wet-eha-thermal-record = wet_eha_thermal.ros.recorder_node:main',
            'wet-eha-thermal-play = wet_eha_thermal.ros.player:main',
        ],
    },
)
