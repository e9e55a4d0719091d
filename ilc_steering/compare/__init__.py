"""``ilc-steering compare``: ILC against RL, black-box and users' learners on one trial counter.

Its arguments (:mod:`.args`), a frozen plan built in one pass (:mod:`.plan`), its cells (:mod:`.cells`),
a committed run beside (:mod:`.against`), its statistics, tables and figures (:mod:`.report`,
:mod:`.tables`), and the command (:mod:`.command`)."""
