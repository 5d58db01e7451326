"""The methods the experiments compare: keyframe selection and in-betweening.

Specification: ``docs/EXPERIMENTS.md`` (the shared research-layer spec). Everything here is a pure
array function, vectorised over measures; the scores are :mod:`dancedata.metrics`, and reading a
store and writing results live in :mod:`dancedata.study` and the CLI.

- :mod:`dancedata.methods.keyframes` — ``even``, ``peaks:*`` and ``dp`` keyframes (§2).
- :mod:`dancedata.methods.keyframes_peaks` — peak picking over 1-d curves (§2.3).
- :mod:`dancedata.methods.keyframes_dp` — Roberts' Salient Poses minimax DP (§2.4).
- :mod:`dancedata.methods.inbetween` — segment maps, linear translation + SLERP (§3.1) and
  the 75-d Euler / 225-d rotation-matrix output layouts.
- :mod:`dancedata.methods.bezier` — cubic Bézier in-betweening, oracle and train-mean (§3.2).
"""
