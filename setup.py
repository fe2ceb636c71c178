"""Reproduction of van Amsterdam et al. (ICRA 2020) on JIGSAWS Suturing kinematics.

Dependency ranges: from the versions the test suite passed with (README, "Tested with") up to the
next major version, which is untested.
"""
from pathlib import Path

from setuptools import find_packages, setup

PAPER = "https://doi.org/10.1109/ICRA40945.2020.9197301"

setup(
    name="mtrnn-jigsaws",
    version="0.1.0",
    description=(
        "Multi-task recurrent network for surgical gesture recognition and progress "
        "prediction (van Amsterdam et al., ICRA 2020) on the DiPietro et al. BiLSTM baseline"
    ),
    long_description=(Path(__file__).parent / "README.md").read_text(encoding="utf-8"),
    long_description_content_type="text/markdown",
    author="The mtrnn-jigsaws developers",
    url=PAPER,
    project_urls={
        "Paper": PAPER,
        "Paper (open access)": "https://arxiv.org/abs/2003.04772",
        "Baseline code (DiPietro et al.)":
            "https://github.com/rdipietro/miccai-2016-surgical-activity-rec",
    },
    license="MIT",
    license_files=["LICENSE"],
    classifiers=[
        "Development Status :: 4 - Beta",
        "Environment :: Console",
        "Intended Audience :: Science/Research",
        "License :: OSI Approved :: MIT License",
        "Operating System :: OS Independent",
        "Programming Language :: Python :: 3",
        "Programming Language :: Python :: 3 :: Only",
        "Programming Language :: Python :: 3.11",
        "Topic :: Scientific/Engineering :: Artificial Intelligence",
        "Topic :: Scientific/Engineering :: Medical Science Apps.",
    ],
    keywords="surgical gesture recognition, progress estimation, multi-task learning, LSTM, "
             "JIGSAWS",
    python_requires=">=3.11",
    packages=find_packages(include=["jigsaws_tools*", "rnn_seg*", "baseline*", "multitask*"]),
    package_data={"jigsaws_tools": ["data/*.csv", "data/tasks/*.toml",
                                   "data/formats/*.toml"],
                  # the fused LSTM loops' source, compiled on first use (rnn_seg/kernels)
                  "rnn_seg": ["kernels/*.cc"]},
    install_requires=[
        "tensorflow-cpu>=2.21,<3",
        "numpy>=2.4,<3",
        "scipy>=1.17,<2",
        "pandas>=3.1,<4",
        "matplotlib>=3.11,<4",
        "rich>=15,<16",             # the grid's live progress (Keras needs it too)
    ],
    extras_require={
        # Dask distributed: runs the grid's jobs on a cluster (multitask-grid --scheduler)
        "dask": ["dask[distributed]>=2026.8"],
        # pytest-xdist: the suite on every core (tests/conftest.py)
        "test": ["pytest>=9,<10", "pytest-xdist>=3.8,<4", "dask[distributed]>=2026.8",
                 "mlflow-skinny>=3.17,<4", "sqlalchemy>=2.1,<3", "alembic>=1.20,<2"],
        # MLflow's tracking client: multitask-train / multitask-grid --mlflow URI; SQLAlchemy and
        # alembic for its database stores (sqlite:///mlflow.db), which mlflow-skinny leaves out
        "mlflow": ["mlflow-skinny>=3.17,<4", "sqlalchemy>=2.1,<3", "alembic>=1.20,<2"],
        # TensorBoard, to view what --tensorboard writes (training writes it without)
        "tensorboard": ["tensorboard>=2.21,<3"],
        # PyTorch, a peer bench/lstm_sweep.py times beside rnn_seg (pinned: numbers name one version)
        "bench": ["torch==2.13.0"],
    },
    entry_points={
        "console_scripts": [
            "jigsaws-tools=jigsaws_tools.cli.main:main",
            "baseline-train=baseline.cli:main",
            "multitask-train=multitask.train_cli:main",
            "multitask-grid=multitask.grid.cli:main",
            "multitask-tables=multitask.evidence.cli:main",
            "multitask-predict=multitask.inference.predict_cli:main",
            "multitask-evaluate=multitask.inference.evaluate_cli:main",
            "multitask-export=multitask.inference.export_cli:main",
        ],
    },
)
