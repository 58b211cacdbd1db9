"""How far to trust a prediction (numpy/scipy only: training calibrates, the predictor applies).

* :mod:`~stiffnet.uncertainty.aggregate`: a recording's (or a trajectory's) windows
  -> mean class probabilities, log beta and the scale of its error.
* :mod:`~stiffnet.uncertainty.conformal`: split-conformal intervals calibrated with one
  score per trajectory, normalised by that scale.
* :mod:`~stiffnet.uncertainty.alarm`: the unreliability alarm - checks on what the model
  looks at (distance of its embedding to the training data's, class ambiguity, beta
  uncertainty), each with a threshold calibrated on in-distribution trajectories.
"""

from stiffnet.uncertainty.aggregate import RecordingEstimate, aggregate_windows
from stiffnet.uncertainty.alarm import AlarmReference, load_alarm, save_alarm
from stiffnet.uncertainty.conformal import conformal_quantile, normalized_scores

__all__ = [
    "AlarmReference",
    "RecordingEstimate",
    "aggregate_windows",
    "conformal_quantile",
    "load_alarm",
    "normalized_scores",
    "save_alarm",
]
