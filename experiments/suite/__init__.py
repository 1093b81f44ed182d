"""The benchmark suites: ``hyst-gym benchmark --suite v1|v2`` (:mod:`experiments.suite.command`).

* :mod:`.common`: what both suites do alike: play an agent on a task's vector env, the design family,
  the design searches, the oracle, the bootstrap helpers, the env speed;
* :mod:`.kinds`: one class per task kind (:class:`~.kinds.ExciteTask`, :class:`~.kinds.CalibrateTask`,
  :class:`~.kinds.JumpTask`): the metric, the agents' estimator, the floor and the kind's own agents;
* :mod:`.v1`, :mod:`.v2`: each suite's profiles, measurement, statistics, report and figure.
"""
