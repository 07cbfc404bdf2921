"""The paper's study: ``plan`` (what is swept; no GL), ``store`` (the typed case record,
results.csv, case files; no GL), ``run`` (the pipelined run on a renderer), ``findings``
(verdicts, advice, report.md) and ``plots``."""
