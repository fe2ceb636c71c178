"""Progress stages from gesture sequences, and the three encodings."""
import numpy as np

from jigsaws_tools.gestures import GESTURE_INDEX, UNLABELLED
from jigsaws_tools.progress import one_hot, ordinal_decode, ordinal_encode, progress_labels


def _codes(*names):
    return np.array([UNLABELLED if n == "-" else GESTURE_INDEX[n] for n in names])


def test_stages_of_a_suturing_sequence():
    seq = _codes("G1", "G5", "G8", "G2", "G3", "G4", "G6", "G9", "G4", "G2", "G3", "G6", "G10",
                 "G8", "G11")
    expected = [0, 0, 1, 1, 2, 3, 3, 3, 1, 1, 2, 3, 3, 4, 4]
    np.testing.assert_array_equal(progress_labels(seq), expected)


def test_adjustments_look_past_unlabelled_frames_and_trailing_ones_keep_stage():
    seq = _codes("-", "G4", "-", "G3", "G6", "G8", "G8", "-")
    np.testing.assert_array_equal(progress_labels(seq), [UNLABELLED, 2, UNLABELLED, 2, 3, 3, 3,
                                                         UNLABELLED])


def test_only_adjustments_is_stage_zero():
    np.testing.assert_array_equal(progress_labels(_codes("G4", "G8")), [0, 0])


def test_encodings():
    p = np.array([0, 2, 4])
    np.testing.assert_array_equal(one_hot(p), np.eye(5)[[0, 2, 4]])
    np.testing.assert_array_equal(ordinal_encode(p), [[1, 0, 0, 0, 0], [1, 1, 1, 0, 0],
                                                      [1, 1, 1, 1, 1]])
    np.testing.assert_array_equal(ordinal_decode(ordinal_encode(np.arange(5))), np.arange(5))


def test_ordinal_decode_uses_first_output_below_half():
    y = np.array([[0.9, 0.8, 0.2, 0.9, 0.9],   # first below 0.5 at index 2 -> stage 1
                  [0.3, 0.9, 0.9, 0.9, 0.9],   # y_0 < 0.5 -> stage 0
                  [0.6, 0.6, 0.6, 0.6, 0.6]])  # none below -> stage 4
    np.testing.assert_array_equal(ordinal_decode(y), [1, 0, 4])
