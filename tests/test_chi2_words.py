"""The reduced chi-square in words names its cause from the data's own noise estimate: a given noise the data show
too small, one they show too large (then the noise is not the cause), or one they agree with."""
from types import SimpleNamespace

from calib.fitreport import chi2_words
from calib.noise import NoiseEstimate


def _fit(red: float):
    return SimpleNamespace(reduced_chi2=red, n_obs=400, free=["a"] * 10, error_scale="inflate")


def _noise(given: float, estimated: float) -> NoiseEstimate:
    return NoiseEstimate(given_mm=given, estimated_mm=estimated, how="target distances", upper_bound=False)


def test_the_cause_follows_the_data_noise():
    assert "the noise given is too small" in chi2_words(_fit(16.0), True, _noise(0.05, 0.2))
    large = chi2_words(_fit(16.0), True, _noise(0.2, 1e-5))       # the TIAGo case: markers of one rigid body
    assert "smaller than the given one" in large and "agrees" not in large
    assert "agrees with the given one" in chi2_words(_fit(16.0), True, _noise(0.2, 0.21))
    assert chi2_words(_fit(1.0), True, _noise(0.2, 0.2)) == ""
