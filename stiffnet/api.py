"""stiffnet from Python: load a model once, then predict and log many records.

The notebook's front door (``docs/python_api.md``)::

    from stiffnet.api import Predictor

    p = Predictor.load()  # models/cnn.onnx, verified against its card
    r = p.predict(x, 2000.0, natural_frequency_hz=9.48)  # a 1-D numpy array
    r["class"], r["beta"], r["beta_interval"], r["alarm"]["message"], r["layers"]
    log = p.log(x, 2000.0, natural_frequency_hz=9.48)  # beta along the record, layers
    r = p.predict_file("rec.csv")  # any registered format; f_n from its sidecar

The objects are the predictor's own (:class:`serving.predictor.Predictor`): the same
results as ``stiffnet predict`` / ``stiffnet log`` and ``POST /predict`` / ``POST /log``,
as JSON-ready dicts. Bad input raises :class:`StiffnetError` with the one-line message
the command line prints.

This module sits above the predictor in the import layers (docs/architecture.md):
the package ``stiffnet`` itself is the base every layer imports, so it cannot reach
up into ``serving``; ``import stiffnet.api`` loads numpy and ONNX Runtime, never
torch, scikit-learn or mlflow.
"""

from __future__ import annotations

from serving.log import stiffness_log
from serving.predictor import Predictor, predict_recording
from stiffnet.errors import StiffnetError

__all__ = ["Predictor", "StiffnetError", "predict_recording", "stiffness_log"]
