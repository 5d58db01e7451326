"""The experiment layer: keyframe selection, in-betweening and their error measures.

Specification: ``EXPERIMENTS.md`` (the shared research-layer spec). Everything here is a pure
array function, vectorised over measures; reading a store and writing results live in
:mod:`dancedata.featurize` and the CLI.

- :mod:`dancedata.methods.keyframes` — ``even``, ``peaks:*`` and ``dp`` keyframes (§2).
- :mod:`dancedata.methods.keyframes_peaks` — peak picking over 1-d curves (§2.3).
- :mod:`dancedata.methods.keyframes_dp` — Roberts' Salient Poses minimax DP (§2.4).
- :mod:`dancedata.methods.inbetween` — segment maps, linear translation + SLERP (§3.1) and
  the 75-d Euler / 225-d rotation-matrix output layouts.
- :mod:`dancedata.methods.bezier` — cubic Bézier in-betweening, oracle and train-mean (§3.2).
- :mod:`dancedata.metrics.reconstruction_error` — the MSE of §4.1 (one named convention).
- :mod:`dancedata.metrics` — every metric of §4 (MSE in all its conventions, FID_k /
  FID_g, diversity, the beat scores, FPD / FMD), each returning value + convention + sample size.
- :mod:`dancedata.study.metric_registry` — the registered metrics (one
  ``metric_<name>.py`` module each): what each needs, its settings, its ``compute``.
- :mod:`dancedata.study.scoring` — scoring generated motion against ground truth per
  sequence and as sets, with every unscored sequence and its reason
  (:mod:`dancedata.metrics.evaluate_inputs`: the conversions it needs).
"""
