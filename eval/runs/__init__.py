"""Runs: a pipeline run anywhere but in this process, contained, limited and cleaned up.

- ``command``: :class:`~arenabench.eval.runs.command.CommandPipeline`, an external command run
  once per image (a team's ``map.py``), cold (a launcher per image, ``launcher``) or warm
  (``warm_client`` in the harness, ``warm_server`` / ``warm_keeper`` / ``warm_up`` around and in
  the sandbox);
- ``sandbox`` and ``interpreter``: bubblewrap's arguments, what an interpreter needs visible;
- ``limits``: the run limits and settings; ``slots``: at most N commands at once;
- ``remover`` and ``stale``: removing runs' folders off the run path, and what killed runs left;
- ``isolated``: a ``pkg.module:function`` in killable child processes;
- ``predictions``: what a run's output becomes (a :class:`Prediction`);
- ``competition_env``: the competition's numpy and OpenCV; ``cmd_script`` and ``run_images``:
  a template's script must exist, the images a run left.

The launcher, the warm server and the keeper run outside the harness's interpreter and use the
standard library only.
"""
