"""ament_python packaging of lit_planner (works with pip, colcon and `ros2 run`)."""

from setuptools import find_packages, setup

package_name = "lit_planner"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="LIT* maintainers",
    maintainer_email="maintainers@lit-star.invalid",
    description=(
        "LIT* planner: C++17 OMPL core (lit_core bindings), planner node, benchmark CLI "
        "and scenario registry."
    ),
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            # The user-facing command and the planner node (`ros2 run lit_planner lit_planner_node`
            # on a ROS install).
            "lit = lit_planner.cli:main",
            "lit_planner_node = lit_planner.node:main",
            "lit_recorder_node = lit_planner.recorder:main",
        ],
    },
)
