"""The live setup page (``planarcal live``, the extra ``planarcal[live]``): a browser page and
its JSON API over a source's frames, to aim, focus, capture placements, calibrate, register
to the robot and watch the parts. See docs/live.md.

frames: the source's newest frame on its own thread; live_detection: the board found fast
enough for every frame; session: the page's state and actions; overlay: what is drawn on
the frames; app: the HTTP server (Starlette)."""
