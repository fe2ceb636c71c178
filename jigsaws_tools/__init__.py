"""JIGSAWS Suturing I/O, preprocessing, annotation versions and progress labels."""
from .dataset import DataConfig, Dataset, Trial, load_dataset
from .preprocessing import Normalisation, PreprocessConfig, preprocess_recording

__all__ = ["DataConfig", "Dataset", "Trial", "load_dataset", "Normalisation", "PreprocessConfig",
           "preprocess_recording"]
