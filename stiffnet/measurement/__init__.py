"""Model versus measurement: evaluate, compare, diagnose, loop, report (issue 6).

One topic per module:

==================  ==================================================================
``statistics``      phase-independent statistics of one record (waveform, spikes,
                    ringing, harmonics, spectrum, inclinations)
``discrepancy``     normalised differences of those statistics -> one discrepancy
``simulate``        a campaign's rows through the simulator, one batch, common random numbers
``evaluate``        learned model and geometric method against the known betas
``compare``         simulator versus measurement: where the model fails
``diagnose``        fit every effect, rank by discrepancy removed, significance
``loop``            add the effect, regenerate, retrain, re-evaluate (MLflow)
``report``          one self-contained HTML page
``plots``           matplotlib figures (imported only by commands and report)
``commands``        the typer commands
==================  ==================================================================

Nothing here imports torch, scikit-learn, mlflow or matplotlib at module level.
"""
