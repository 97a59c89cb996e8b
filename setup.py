# Installs the Python libraries under src/ for catkin (catkin_python_setup).
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(
    packages=["fastslam", "fastslam.filter", "fastslam.match", "fastslam.io", "fastslam.eval", "fastslam.sim",
              "assign5"],
    package_dir={"": "src"},
))
