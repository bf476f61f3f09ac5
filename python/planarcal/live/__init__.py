"""The production loop: frames in (``capture``), parts found and mapped (``objects``),
followed from frame to frame (``tracker``), results out (``outputs``), and ``run`` tying
them together for ``planarcal run``. Everything here runs per frame, after calibration.
"""
