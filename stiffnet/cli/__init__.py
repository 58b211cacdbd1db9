"""The command line, one package: the ``stiffnet`` typer app (:mod:`.app`), what every
command shares (:mod:`.console`: consoles, JSON output, one-line errors, tables that
fit, progress; :mod:`.options`: options several commands take), and one module per
command group: :mod:`.predict` (``predict``, ``predict-batch``, ``serve``, ``log``) and
:mod:`.measurement` (``evaluate``, ``compare``, ``diagnose``, ``loop``, ``report``).
The top of the house: nothing below imports it.
"""

from stiffnet.cli.app import app, main

__all__ = ["app", "main"]
