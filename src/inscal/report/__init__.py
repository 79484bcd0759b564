"""Rendering: figures (:mod:`~inscal.report.figures`), HTML blocks, the record report, the path section
and the demo report.  It renders and may call analysis and plan; it implements neither."""
