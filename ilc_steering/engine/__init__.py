"""The engine that compare and sweep share: a run folder and its grid of cells (:mod:`.runs`),
where the cells run (:mod:`.backends`: local processes or Ray tasks) and what made a run
(:mod:`.provenance`: code hash, commit, packages, sessions; ``ilc-steering current``)."""
