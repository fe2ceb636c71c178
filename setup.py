"""Reproduction of van Amsterdam et al. (ICRA 2020) on JIGSAWS Suturing kinematics."""
from setuptools import find_packages, setup

setup(
    name="mtrnn-jigsaws",
    version="0.1.0",
    description=(
        "Multi-task recurrent network for surgical gesture recognition and progress "
        "prediction (van Amsterdam et al., ICRA 2020) on the DiPietro et al. BiLSTM baseline"
    ),
    python_requires=">=3.11",
    packages=find_packages(include=["jigsaws_tools*", "rnn_seg*", "baseline*", "multitask*"]),
    package_data={"jigsaws_tools": ["data/*.csv", "data/tasks/*.toml"]},
    install_requires=[
        "tensorflow-cpu>=2.15",
        "numpy>=1.24",
        "scipy>=1.10",
        "pandas>=2.0",
        "matplotlib>=3.7",
    ],
    extras_require={
        # Dask distributed: runs the grid's jobs on a cluster (multitask-grid --scheduler)
        "dask": ["dask[distributed]>=2023.1"],
        "test": ["pytest>=7", "dask[distributed]>=2023.1"],
    },
    entry_points={
        "console_scripts": [
            "jigsaws-tools=jigsaws_tools.cli:main",
            "baseline-train=baseline.cli:main",
            "multitask-train=multitask.train_cli:main",
            "multitask-grid=multitask.grid_cli:main",
            "multitask-tables=multitask.tables_cli:main",
            "multitask-predict=multitask.predict_cli:main",
            "multitask-evaluate=multitask.evaluate_cli:main",
            "multitask-export=multitask.export_cli:main",
        ],
    },
)
