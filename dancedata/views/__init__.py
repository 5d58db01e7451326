"""Views over the thin store reader (:class:`dancedata.sequence_reader.SequenceReader`).

Each module has one job and reads the store only through the reader's public methods:

* :mod:`~dancedata.views.fact` and :mod:`~dancedata.views.thesis` — the papers' layouts
  (FACT 225/35; the thesis's 75/22/88 and its weighted onset curves);
* :mod:`~dancedata.views.layouts` — every layout by name, which are motion and which audio;
* :mod:`~dancedata.views.assemble` — a layout's arrays read and put side by side;
* :mod:`~dancedata.views.measures` — measures of a split as view windows;
* :mod:`~dancedata.views.cameras` — the AIST++ cameras of a sequence.

:class:`dancedata.loader.DanceStore` exposes them as methods (``store.view(...)``).
"""
