"""Wheel-flat diagnosis: fit the twin's physics to a measured wheel passage.

One concept per module:

| module | concept |
|---|---|
| ``combined`` | the combined irregularity: a wheel's table on an even rail plus a round wheel's table on the rail |
| ``sensor`` | the site's measuring chain: causal Butterworth low-pass, sampling |
| ``forward`` | one flat wheel's passage (with its run-in) and the once-per-turn impact window |
| ``turns`` | where the flat meets the rail: turn times, phase, event detection in a measured record |
| ``estimate`` | the coarse-to-fine fit of kind, length, depth and phase with a length interval |
| ``verdict`` | limits from practice and the ``ok``/``watch``/``inspect``/``remove`` verdict |
| ``crib_screen`` | a round wheel's crib channels without simulation (the template), the record's noise, the screen |
| ``crib_forward`` | the twin's crib channels: a wheel on the site's track through the site's chain |
| ``crib_fit`` | the fit of kind, length and phase to measured crib channels, with a length interval |
| ``synthetic`` | synthetic measured passages with what the twin does not model (validation) |

Nothing here does I/O: the service turns messages into these plain inputs.
"""
