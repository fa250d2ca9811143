"""Calibration of a site's track from the round wheels that pass it (issue 26, docs/calibration.md).

A round wheel's channel is statically P inside its crib and 0 outside, whatever the track;
the track shows only through the dynamics (the dynamic wheel load from sleeper passing, the
rail's inertia between the gauges, the chain's response to both). The modules, one concept
each, no I/O:

- ``forward``: what a detector records of a round wheel on a given track (``predict_channels``);
- ``crib_chain``: a crib's channel through the measuring chain in one pass (``forward``'s last step);
- ``parameters``: the track's calibrated parameters as a vector of log-factors on the nominal;
- ``residuals``: a calibration passage and its noise-weighted channel residuals, the noise
  estimated from the record;
- ``sensitivities``: the residuals' Jacobian in the log-factors (finite differences on a few
  reductions of the track);
- ``estimator``: Gauss–Newton on the weighted residuals with a prior on the log-factors, the
  covariance from the Fisher information and a jackknife over the wheels;
- ``identifiability``: which parameters and which combinations the data cannot tell apart
  (the Fisher matrix's eigenvectors against the prior);
- ``recursive``: the calibration learned wheel by wheel (the twin's), its step per wheel and
  its range limited.
"""
