"""The camera itself: OpenCV intrinsics from several board views, their file formats, the
pose of the plane and heights above it. Separate from ``calib`` because a plane's
calibration needs none of it; only objects of known height do.
"""
