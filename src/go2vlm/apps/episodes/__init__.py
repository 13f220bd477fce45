"""Episodes: the one runner behind `go2vlm demo`, `go2vlm demo --goal` and `go2vlm eval`.

episode.py   what an episode is (world, spawn, task, perception variant) and its launch graph
recorder.py  the one recorder node
metrics.py   the one metrics module (success, SPL, collisions, grounding IoU, ...)
runner.py    run one episode in this process and write its run folder
video.py     the chase-camera video, rendered after the run; plot.py: plot.png
demo.py      `go2vlm demo [--goal]`: one episode, a progress bar, a summary
suites.py    suite files (suites/*.yaml) -> seeded episodes
evaluate.py  `go2vlm eval`: many episodes, worker processes, results.jsonl, resume
report.py    summary.json (with confidence intervals), report.md and its plots
"""

from go2vlm.apps.episodes.episode import PERCEPTIONS, Episode
from go2vlm.apps.episodes.runner import EpisodeResult, RunOptions, run_episode

__all__ = ["PERCEPTIONS", "Episode", "EpisodeResult", "RunOptions", "run_episode"]
