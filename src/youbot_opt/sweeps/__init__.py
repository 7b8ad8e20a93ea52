"""The crash-safe sweep engine (layer L2): it knows nothing of robots.

Modules: :mod:`.options` (:class:`~youbot_opt.sweeps.options.SweepOptions`, how every
sweep runs), :mod:`.pool` (the crash-isolating worker pool and ``run_tasks``),
:mod:`.tasks` (tasks, outcomes, retry queues), :mod:`.distributed` and :mod:`.scheduler`
(Dask), :mod:`.store` (the resumable on-disk store), :mod:`.records` and :mod:`.journal`
(its item files and summary journal), :mod:`.resume` (the item loop over the store),
:mod:`.worker_solver` (a built solver per worker), :mod:`.optima` (distinct local optima),
:mod:`.multistart` (one multistart result, local optimum and tally), :mod:`.forked` (one
call in a forked process). Trajectory and IK-path sweeps supply tasks and payloads.

    from youbot_opt.sweeps.options import SweepOptions
"""
