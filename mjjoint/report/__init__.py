"""Reports of ``mjjoint fit`` and ``mjjoint diagnose``: JSON, PNGs, index.html, traces.rrd, text.

``build`` writes a whole output folder (into a partial folder that ``output`` renames only
when complete); ``compare`` predicts the recording's windows with the fitted models once;
``plots`` and ``evidence`` draw from that; ``html``, ``rrd`` and ``summary`` present it.
Nothing is imported here, so the command line starts without matplotlib and rerun.
"""
