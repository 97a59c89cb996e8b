# Installs the Python libraries under src/ for catkin (catkin_python_setup).
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(
    packages=["fastslam", "fastslam.sim", "fastslam.io", "assign5"],
    package_dir={"": "src"},
))
