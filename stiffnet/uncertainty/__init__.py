"""How far to trust a prediction: the one home of intervals, the alarm and the OOD reference.

numpy/scipy only: training fits here, the predictor applies from here, side by side.

* :mod:`~stiffnet.uncertainty.aggregate`: a recording's (or a trajectory's) windows
  -> mean class probabilities, log beta and the scale of its error.
* :mod:`~stiffnet.uncertainty.conformal`: split-conformal intervals calibrated with one
  score per trajectory, normalised by that scale (:func:`conformal_quantile`), and
  applied to a recording (:func:`beta_interval`).
* :mod:`~stiffnet.uncertainty.alarm`: the unreliability alarm's reference - checks on
  what the model looks at (distance of its embedding to the training data's, class
  ambiguity, beta uncertainty, class edge), each with a threshold calibrated on
  in-distribution trajectories; saved beside the model (``NAME.alarm.npz``).
* :mod:`~stiffnet.uncertainty.alarm_verdict`: the alarm applied to one recording, in
  words (with the restoring-force check).
* :mod:`~stiffnet.uncertainty.ood`: the inclination-feature OOD reference (fitted by
  ``training/fit_ood_reference.py``, the fallback alarm of older models).
"""

from stiffnet.uncertainty.aggregate import RecordingEstimate, aggregate_windows
from stiffnet.uncertainty.alarm import AlarmReference, load_alarm, save_alarm
from stiffnet.uncertainty.conformal import beta_interval, conformal_quantile, normalized_scores

__all__ = [
    "AlarmReference",
    "RecordingEstimate",
    "aggregate_windows",
    "beta_interval",
    "conformal_quantile",
    "load_alarm",
    "normalized_scores",
    "save_alarm",
]
