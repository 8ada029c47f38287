"""The training's callbacks: a progress bar and the periodic evaluation.

SB3's own ``EvalCallback`` scores a policy by its returns only, through Monitor wrappers;
the periodic evaluation here runs the same exact rollout as the final evaluation
(stick-time fraction, effort, return on fixed episodes), so the learning curve and the
results table measure the same thing. SB3's ``ProgressBarCallback`` cannot show the latest
evaluation, which the bar here carries in its postfix. Both are module-level classes, so
they can be imported, subclassed and pickled. This module imports torch (through SB3):
import it only when training starts.
"""

from __future__ import annotations

import csv
import time
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from .rollouts import EpisodeMetrics, TrainedController, rollout


class ProgressBar(BaseCallback):
    """tqdm bar over timesteps with the latest evaluation in the postfix."""

    def __init__(self, total: int, status: dict[str, Any], enabled: bool = True):
        super().__init__()
        self.total = total
        self.status = status
        self.enabled = enabled
        self.bar: Any = None  # a tqdm bar from the training's start
        self._done = 0

    def _on_training_start(self) -> None:
        from fricenv.progress import tqdm  # (its rate leaves out compile time)

        self.bar = tqdm(total=self.total, unit="step", disable=not self.enabled,
                        dynamic_ncols=True, desc="train")

    def _on_step(self) -> bool:
        step = min(self.num_timesteps, self.total)
        self.bar.update(step - self._done)
        self._done = step
        if self.status.get("dirty"):
            self.status["dirty"] = False
            self.bar.set_postfix(eval_return=f"{self.status['return']:.2f}",
                                 stick=f"{self.status['stick']:.4f}", refresh=False)
        return True

    def _on_training_end(self) -> None:
        self.bar.close()


class PeriodicEval(BaseCallback):
    """Deterministic evaluation every ``eval_freq`` steps on the same fixed episodes.

    Uses the evaluation code of ``fricenv_agents.evaluate`` (exact stick fraction, effort,
    return), so the learning curve and the final table measure the same thing. Results
    are only logged, never used to pick a checkpoint: the final model is the result.
    """

    def __init__(self, scene: str, env_kwargs: dict, seed: int, n_episodes: int,
                 eval_freq: int, run_dir: Path, status: dict[str, Any]):
        super().__init__()
        self.scene, self.env_kwargs, self.seed = scene, env_kwargs, seed
        self.n_episodes, self.eval_freq = n_episodes, eval_freq
        self.run_dir, self.status = run_dir, status
        self.next_eval = 0
        self.rows: list[dict[str, float]] = []
        self.returns: list[np.ndarray] = []
        self.lengths: list[np.ndarray] = []

    def _evaluate(self) -> None:
        ctrl = TrainedController(self.model, self.model.get_vec_normalize_env())
        m: EpisodeMetrics = rollout(ctrl, self.scene, self.seed, self.n_episodes,
                                    self.env_kwargs)
        row = {"timesteps": self.num_timesteps, "time_s": time.perf_counter() - self.t0,
               "return_mean": float(m.ret.mean()), "return_std": float(m.ret.std()),
               "stick_fraction": float(m.stick_fraction.mean()),
               "effort": float(m.effort.mean()),
               "rms_vr_fluct": float(m.rms_vr_fluct.mean())}
        self.rows.append(row)
        self.returns.append(m.ret)
        self.lengths.append(m.length)
        for key in ("return_mean", "stick_fraction", "effort"):
            self.logger.record(f"eval/{key}", row[key])
        self.status.update({"return": row["return_mean"], "stick": row["stick_fraction"],
                            "dirty": True})
        self._write()

    def _write(self) -> None:
        np.savez(self.run_dir / "evaluations.npz",
                 timesteps=np.array([r["timesteps"] for r in self.rows]),
                 results=np.array(self.returns), ep_lengths=np.array(self.lengths),
                 stick_fraction=np.array([r["stick_fraction"] for r in self.rows]),
                 effort=np.array([r["effort"] for r in self.rows]))
        with open(self.run_dir / "eval_log.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(self.rows[0]))
            w.writeheader()
            w.writerows(self.rows)

    def _on_training_start(self) -> None:
        self.t0 = time.perf_counter()
        self.next_eval = self.eval_freq
        self._evaluate()  # the untrained policy: where the learning curve starts

    def _on_step(self) -> bool:
        if self.eval_freq > 0 and self.num_timesteps >= self.next_eval:
            self._evaluate()
            while self.next_eval <= self.num_timesteps:
                self.next_eval += self.eval_freq
        return True

    def _on_training_end(self) -> None:
        if not self.rows or self.rows[-1]["timesteps"] != self.num_timesteps:
            self._evaluate()  # the curve always ends at the final model
