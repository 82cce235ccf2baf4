"""Runs: a pipeline run anywhere but in this process, contained, limited and cleaned up.

This package is the one door into running untrusted code: the rest of arenabench imports the
names below from ``arenabench.eval.runs``, never its modules (``tests/test_import_graph.py``).

    from arenabench.eval.runs import CommandPipeline, RunContext, RunSettings

    with RunContext(slots=workers) as runs:        # slots, folder remover, warm servers
        pipe = CommandPipeline("python3 map.py --image {image}", settings=RunSettings(),
                               context=runs)
        prediction = pipe.run(image_path)          # never raises for the command's failures

Modules, by what they hold:

- ``pipeline``: :class:`CommandPipeline`, an external command run once per image (a team's
  ``map.py``); ``context``: :class:`RunContext`, what one evaluation's runs share; ``command``:
  a template prepared once (:class:`~.command.Command`) and the :class:`~.command.Runner`
  interface; ``cold`` (a launcher per image, ``launcher``) and ``warm_client`` (a warm
  interpreter per command; ``warm_server``, ``warm_keeper``, ``warm_up`` run around and in
  the sandbox) are the two runners;
- ``proctools``: the process, namespace, mount and cgroup helpers the launcher, the warm
  server, the keeper and the harness share (standard library only);
- ``sandbox`` and ``interpreter``: bubblewrap's arguments, what an interpreter needs visible;
- ``limits``: the run limits and settings; ``slots``: at most N commands at once;
- ``remover`` and ``stale``: removing runs' folders off the run path, and what killed runs left;
- ``isolated``: a ``pkg.module:function`` in killable child processes;
- ``predictions``, ``outputs`` and ``run_images``: what a finished run's files and output come
  to (a :class:`~arenabench.eval.scoring.results.Prediction`);
- ``competition_env``: the competition's numpy and OpenCV; ``cmd_script``: a template's script
  must exist.

The launcher, the warm server and the keeper run outside the harness's interpreter and use the
standard library only.
"""

from .cmd_script import missing_script_problem
from .competition_env import (
    COMPETITION_PINS,
    COMPETITION_PLACEHOLDER,
    OWN_PYTHON_PLACEHOLDER,
    Interpreter,
    competition_python,
    resolve_competition_python,
    substitute_competition_python,
    uses_competition_python,
)
from .context import RunContext
from .interpreter import InterpreterInfo, interpreter_folders
from .isolated import IsolatedCallablePipeline, trial_pipeline
from .limits import RunLimits, RunSettings, run_settings_from_args
from .pipeline import CommandPipeline, check_command
from .predictions import OUTPUT_MODES, STARVED_RETRIES, STARVED_SHARE
from .run_images import collect_run_images
from .sandbox import bwrap_problem, pids_cgroup_parent
from .stale import owned_dir_prefix, sweep_stale_runs
from .warm_up import warm_up

__all__ = [
    "COMPETITION_PINS",
    "COMPETITION_PLACEHOLDER",
    "OUTPUT_MODES",
    "OWN_PYTHON_PLACEHOLDER",
    "STARVED_RETRIES",
    "STARVED_SHARE",
    "CommandPipeline",
    "Interpreter",
    "InterpreterInfo",
    "IsolatedCallablePipeline",
    "RunContext",
    "RunLimits",
    "RunSettings",
    "bwrap_problem",
    "check_command",
    "collect_run_images",
    "competition_python",
    "interpreter_folders",
    "missing_script_problem",
    "owned_dir_prefix",
    "pids_cgroup_parent",
    "resolve_competition_python",
    "run_settings_from_args",
    "substitute_competition_python",
    "sweep_stale_runs",
    "trial_pipeline",
    "uses_competition_python",
    "warm_up",
]  # fmt: skip
