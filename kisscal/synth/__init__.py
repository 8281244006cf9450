"""Synthetic rigs with ground truth: cameras, lenses, motions, rendered images.

:mod:`~kisscal.synth.presets` describes kinds of labs and draws one rig from a seed,
:mod:`~kisscal.synth.plan` decides a whole session and renders it camera by camera,
:mod:`~kisscal.synth.truth` says what detection should find in it, and
:mod:`~kisscal.synth.busy` draws a busy benchmark frame. Everything here is pure;
:mod:`kisscal.session.synth_session` writes the files (``kisscal synth``).
"""
