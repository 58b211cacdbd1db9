"""Model versus measurement: evaluate, compare, diagnose, loop, report (issues 6, 13).

One topic per module:

==================  ==================================================================
``statistics``      phase-independent statistics of one record (waveform, spikes,
                    ringing, harmonics, spectrum, inclinations)
``discrepancy``     normalised differences of those statistics -> one discrepancy
``simulate``        a campaign's rows through the simulator, one batch, common random numbers
``evaluate``        learned model and geometric method against the known betas
``compare``         simulator versus measurement: where the model fails
``target``          what a fit compares against: rows, measured statistics, base model
``fitting``         one effect on top of a model, or all jointly (each effect's fit space)
``significance``    paired tests on per-recording discrepancies, reasons in words
``noise_floor``     the campaign's own noise floor (split halves) and the verdict
``nuisance``        manifest gaps: forcing frequency, gap, damping, beta, initial state
``diagnose``        forward selection with joint refits, the verdict (orchestration)
``loop``            add the effect, regenerate, retrain, re-evaluate (MLflow)
``report``          one self-contained HTML page
``plots``           matplotlib figures (imported only by commands and report)
``commands``        the typer commands
==================  ==================================================================

Nothing here imports torch, scikit-learn, mlflow or matplotlib at module level.
"""
