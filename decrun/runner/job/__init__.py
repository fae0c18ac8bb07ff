"""One run: its config composed and checked (:mod:`~decrun.runner.job.config`,
:mod:`~decrun.runner.job.plugins`, :mod:`~decrun.runner.job.experiment`), then prepared, executed
and written (:mod:`~decrun.runner.job.run`), with its context, progress, failures and hints."""
