"""railtwin's physics: vibro-impact rolling contact of a wheel on a rail (MODEL.md).

Pure functions and plain arrays: no I/O, no Zenoh, MCAP or Rerun here.
"""
