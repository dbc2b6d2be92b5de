"""ament_python packaging of lit_learner (works with pip, colcon and `ros2 run`)."""

from setuptools import find_packages, setup

package_name = "lit_learner"

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
        "LIT* learner: Fuzzy-DDPG policy for batch size B and neighbour factor psi_K, "
        "learner node and tensor export."
    ),
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={"console_scripts": ["lit_learner_node = lit_learner.node:main"]},
)
