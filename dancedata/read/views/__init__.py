"""Views over the thin store reader (:class:`dancedata.read.sequence_reader._SequenceReader`).

Each module has one job and reads the store only through the reader's public methods:

* :mod:`~dancedata.read.views.fact` and :mod:`~dancedata.read.views.thesis` — the papers' layouts
  (FACT 225/35; the thesis's 75/22/88 and its weighted onset curves);
* :mod:`~dancedata.read.views.layouts` — every layout by name, which are motion and which audio;
* :mod:`~dancedata.read.views.assemble` — a layout's arrays read and put side by side;
* :mod:`~dancedata.read.views.measures` — measures of a split as view windows;
* :mod:`~dancedata.read.views.cameras` — the AIST++ cameras of a sequence.

:class:`dancedata.read.loader.DanceStore` exposes them as methods (``store.view(...)``).
"""
