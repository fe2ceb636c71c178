"""JIGSAWS Suturing I/O, preprocessing, annotation versions and progress labels."""
from .dataset import DataConfig, Dataset, Trial, load_dataset
from .preprocessing import PreprocessConfig

__all__ = ["DataConfig", "Dataset", "Trial", "load_dataset", "PreprocessConfig"]
