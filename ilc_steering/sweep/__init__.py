"""``ilc-steering sweep``: robustness maps, trials to tolerance over a grid of true plants.

Its rows (:mod:`.rows`: plants, the oracle's calls, readers), its reports (:mod:`.report`) and the
command (:mod:`.command`)."""
