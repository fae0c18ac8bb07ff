"""The file-system helpers every output goes through: file names of a run and a sweep
(:mod:`~decrun.runner.io.files`), atomic writes, locks, paths kept inside their directory, YAML
text, interrupts held off while a file is finished, the job cache."""
