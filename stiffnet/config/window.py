"""The model window's geometry: one source for the dataset, CNN and predictor defaults.

A model window holds :data:`WINDOW_PERIODS` natural periods of the recording:
the dataset cuts its windows to it (``WindowConfig.duration_periods``), the CNN
resamples each window to :data:`CANONICAL_RATE` samples per natural period over
as many periods (``CNNConfig.rate``, ``CNNConfig.periods``, with delay channels
:data:`DELAY_FRACTION` natural periods apart), and the predictor cuts a
recording the same way when a model's metadata does not say
(:mod:`stiffnet.features.windows`). Plain numbers, no imports: the light
predictor reads them too.
"""

#: Natural periods per model window (16 gives the geometric method 15-20 orbits).
WINDOW_PERIODS = 16
#: Canonical samples per natural period of the CNN's input.
CANONICAL_RATE = 32
#: Delay of the CNN's embedded channels in natural periods (the geometric method's rule).
DELAY_FRACTION = 0.18
