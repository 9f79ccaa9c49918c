"""Use cases: one module per algorithm of the provider. Each takes plain inputs (files, names,
numbers, a request dataclass), checks them once, does the work with the lower layers and returns a
:class:`core.runs.base.RunResult` (the files written, the figures, the log lines). The Processing
algorithms of ui/algorithms/ convert their parameters to a request and make one call."""
