"""Finger-skin study outputs: the paper's Figs 3–6 (:mod:`~feeler.skin.figures`) and the
fidelity-ladder study of L0/L1/L2 (:mod:`~feeler.skin.study`)."""
