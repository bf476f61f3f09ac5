"""The plane's calibration: the board, finding it in an image, and fitting the plane.

``board`` is what is printed, ``blobs`` / ``grid_search`` / ``dot_centres`` / ``detect`` find
it, and ``calibration`` fits the homography and lens model and saves them. One subpackage
because everything here turns one picture of one board into one ``Calibration``.
"""
