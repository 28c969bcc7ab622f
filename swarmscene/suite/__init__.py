"""swarmscene-bench: standard swarm tasks, standard metrics, reference results (docs/suite.md).

* :mod:`.definition`: the tasks of a suite version (the ``task`` config group), their canonical
  definitions and the hash each version is frozen under (:data:`.definition.FROZEN`);
* :mod:`.score`: a sweep's runs scored against their task (raw and normalised score, pass rule),
  refusing a run whose task was changed;
* :mod:`.stats`: the statistics the field reports (rliable: IQM and mean with stratified
  bootstrap intervals, probability of improvement, performance profiles);
* :mod:`.results`: the files a scored sweep leaves (per-run scores, marl-eval's JSON, the
  aggregates) and the reference results shipped with the package;
* :mod:`.callback`: the Hydra callback of ``+sweep=suite_v1`` that writes them;
* :mod:`.page`: the leaderboard page (docs/suite.md) and its pictures.
"""
