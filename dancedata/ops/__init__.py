"""Operations on parsed files: where a format meets the array maths.

:mod:`dancedata.io` parses and writes files and imports nothing of :mod:`dancedata.compute`;
compute is pure array code and imports nothing of io. The few functions that need both sit
here, above the two (fairmotion keeps formats apart from operations the same way):

* :mod:`~dancedata.ops.bvh_clip` — a :class:`~dancedata.io.bvh.BvhClip`'s local rotations,
  forward kinematics, resampling, and a clip built back from rotation matrices;
* :mod:`~dancedata.ops.smpl_skeletons` — the SMPL skeleton (rest offsets and parents) from a
  model file, or the built-in table, with the name that records which one was used.
"""
