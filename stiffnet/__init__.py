"""stiffnet: identify the stiffness of an impacted material from one accelerometer.

Implements the impact oscillator of the founding paper (eqs 11-12) with a library
of physical effects, nonlinear time-series analysis and the geometric
(tangent-vector inclination) stiffness method, learned models and a light
ONNX predictor.
"""

__version__ = "0.1.0"
