"""The lightweight ONNX predictor (``stiffnet predict``, ``stiffnet serve``).

Installs with stiffnet's core plus the ``serve`` extra; imports numpy, scipy,
onnxruntime and stiffnet's numpy-only modules, never torch, scikit-learn or
mlflow. Modules: :mod:`serving.predictor` (``Predictor``, ``predict_recording``),
:mod:`serving.model` (verified ONNX loading), :mod:`serving.families` (what each
model family reads from the windows), the pipeline's steps :mod:`serving.checks`,
:mod:`serving.aggregate`, :mod:`serving.restoring_force_check`, :mod:`serving.schemas`,
:mod:`serving.app` (FastAPI), :mod:`serving.log` (the stiffness log along a record,
with :mod:`serving.stream` and :mod:`serving.log_plot`), :mod:`serving.batch_prediction`
(``predict-batch``) and :mod:`stiffnet.cli.predict` (CLI); the interval, the alarm and
the OOD reference are applied from :mod:`stiffnet.uncertainty`, where training fits
them. Nothing is imported here, so that ``stiffnet
--help`` stays fast. See ``docs/serving.md``.
"""
