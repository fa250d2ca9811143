"""The integrator of the lumped models (rigid ground, the paper's mass on a spring): one concept,
one package.

- ``tableau``: explicit Runge–Kutta tableaus as data (``Tableau``: DOP853, DOPRI5);
- ``step``: the one compiled Runge–Kutta step any of them drives;
- ``types``: what the compiled integrator is handed and returns (``Table``, ``Params``, ``Event``);
- ``model``: the vector field of MODEL.md §4 and what a step's dense output gives;
- ``dense``: the dense output of a step;
- ``events``: detecting and locating contact events inside a step;
- ``records``: samples, extrema and dent records read off each step;
- ``loop``: step-size control, landing on events, and ``integrate`` itself;
- ``dop853``, ``dopri5``: the coefficients (SciPy's, BSD-3).

The rail on supports (``sim_core.track``) has its own exact-mode stepper; both sit behind
``sim_core.under_rail.UnderRail``.
"""
