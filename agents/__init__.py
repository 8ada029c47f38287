"""Training, baselines and evaluation of stick-slip suppression controllers.

The folder ``agents/`` installs as ``fricenv_agents``, an import name of its own (other
distributions install a top-level ``agents``). ``fricenv train`` and ``fricenv evaluate``
reach :mod:`.train` and :mod:`.evaluate` through the ``fricenv.commands`` entry points.
Modules by concern: ``layout`` (names, seed layout), ``config`` (hyperparameter files),
``envs`` (the training environment), ``rollouts`` (controllers, scoring), ``runs`` (run
folders, loading models), ``callbacks`` (training callbacks), ``cli`` (shared command-line
pieces), ``scoring`` (the evaluation's tables and plots), ``statistics`` (interquartile
means, bootstrap intervals, performance profiles), ``imitation`` (warm starts from the
MPC), ``throughput`` (plant-steps and PPO samples per second), ``mpc_tuning`` (the search
behind the MPC's per-scene settings), ``mpc_compare`` (PPO against the tuned MPC on the
benchmark's episodes), ``noise_report`` (returns under noise and delay), and
``baselines``, ``mpc``, ``benchmark`` (with its ``benchmark_figures``,
``benchmark_records`` and ``benchmark_workers``). ``train`` and
``evaluate`` import numba, torch and stable-baselines3 only after parsing their command
line, so that their ``--help`` stays quick.
"""
