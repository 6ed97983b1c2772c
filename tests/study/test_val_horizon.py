"""``study.val_horizon`` is bounded by the validation length, before any run: at most half of the
validation samples, so that at least half of the k-step predictions start from a measured output
(the first k come from the initial state alone).  It accepted 874 on 875 validation samples, and
logged a val_fit of 100 % for a model whose simulation FIT was 6.5 %."""

from __future__ import annotations

import pytest

from maglev.structures import PolySpec
from maglev.study.config import StudyConfigError, check_lengths

# binary_a025 in the tests' TINY form: 4000 samples, trim 500, decimate 2, split 0.5 → 875 + 875
DATASET = {"name": "binary_a025", "preprocess": {"trim": 500, "decimate": 2, "split": 0.5}}
ARX = PolySpec.from_orders("arx", (2, 2, 1))


def test_a_horizon_of_half_the_validation_samples_is_accepted_one_more_is_refused_naming_the_key():
    check_lengths(DATASET, ARX, {"resid_lags": 25, "val_horizon": 437}, 4000)
    with pytest.raises(StudyConfigError) as refused:
        check_lengths(DATASET, ARX, {"resid_lags": 25, "val_horizon": 438}, 4000)
    message = str(refused.value)
    assert message.startswith("study.val_horizon=438: dataset 'binary_a025' (4000 samples; trim 500, decimate 2, "
                              "split 0.5) leaves 875 estimation and 875 validation samples"), message
    assert "the validation at least 876" in message and "study.val_horizon=438 at most half" in message
    assert message.endswith("changing dataset.preprocess.trim=500 or dataset.preprocess.decimate=2 alone would also do")
    assert "\n" not in message
