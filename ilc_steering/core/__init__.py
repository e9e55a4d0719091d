"""The mathematics of the paper, free of Gymnasium, YAML, environments and agents.

- :mod:`~ilc_steering.core.chained_form`: eq. 1, ``A(v1)`` (eq. 14), ``V`` and ``W`` (eqs. 21-25);
- :mod:`~ilc_steering.core.profiles`: the :class:`InputProfile` protocol and eqs. 15-17;
- :mod:`~ilc_steering.core.robots`: one module per robot (map, plant, compiled field, config keys,
  drawing) and their registry; :mod:`~ilc_steering.core.robots.car`: eq. 3, ``alpha``,
  ``alpha^-1``, ``beta`` (eqs. 4-5), the frame rotation;
- :mod:`~ilc_steering.core.nominal`: the :class:`NominalModel` a learner sees;
- :mod:`~ilc_steering.core.plants`: what every robot shares: the :class:`Plant` protocol, the kernel
  and its named layout;
- :mod:`~ilc_steering.core.stepper`: the compiled integrator's core (numba); :mod:`~ilc_steering.core.integrate`,
  the checked boundary into it; :mod:`~ilc_steering.core.simulate`: batches of trials;
- :mod:`~ilc_steering.core.dop853`: its Runge-Kutta tableau;
- :mod:`~ilc_steering.core.reference`: tight ``solve_ivp`` trials, for tests and benchmarks;
- :mod:`~ilc_steering.core.trajectory`: a recorded trial;
- :mod:`~ilc_steering.core.checks`: the range rules of the domain objects.

Import the modules themselves; this package's ``__init__`` imports nothing.
"""

__all__: list[str] = []
