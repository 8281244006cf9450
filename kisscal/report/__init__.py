"""Figures and the HTML session report.

Stage figures (drawn by the session stages into ``out/figures/``): :mod:`.grid`,
:mod:`.dlt`, :mod:`.epipolar`, :mod:`.tracking`, :mod:`.overlay`. The report
(:func:`kisscal.report.html.build_report`): :mod:`.gather` reads ``out/``, :mod:`.markers`
and :mod:`.validation` measure the trajectories, :mod:`.status` judges them against
:class:`~kisscal.report.params.ReportParams`, the ``page_*`` modules write the sections,
:mod:`.viewer` the offline 3D viewer and :mod:`.figures` the report's own figures.
"""
