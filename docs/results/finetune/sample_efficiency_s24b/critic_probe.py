"""The critics of an RLPD run (its last.ckpt): their value of the demonstrations' filling
steps (demonstrated boom command <= 0), minimum over the ensemble, against those steps'
Monte-Carlo discounted return (gamma 0.997). Settings as in the sample-efficiency runs
(critic_hidden [64, 64]); residual / calibrated read from the run directory's name.

Usage: PYTHONPATH=<repo>:<repo>/envs python critic_probe.py CLONE.pt DEMOS_DIR RUN_DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import torch

from pilerl.data.store import EpisodeStore
from pilerl.policies import load_actor
from pilerl.rl import RLPDConfig
from pilerl.rl.calibration import monte_carlo_returns
from pilerl.rl.rlpd import RLPDLearner
from pilerl.rl.run_checkpoint import load_run

clone, demos_dir, run = sys.argv[1], sys.argv[2], Path(sys.argv[3])
residual = "residual" in str(run)
settings = RLPDConfig(
    utd_ratio=0.2,
    warmup_utd_ratio=0.5,
    batch_size=128,
    critic_hidden=[64, 64],
    residual=residual,
    calibrated_critic="calibrated" in str(run),
)
demos = EpisodeStore.open(demos_dir).to_tensordict()
learner = RLPDLearner(load_actor(clone), settings, demos=demos)
_, state, _ = load_run(run / "last.ckpt")
learner.load_state_dict(state, path=run / "last.ckpt")
returns, known = monte_carlo_returns(demos, settings.gamma)
filling = (demos["action"][:, 0] <= 0) & known
data = demos.select(*learner.loss.qvalue_network.in_keys)[filling]
with torch.no_grad():
    q = (
        learner.loss._vmap_qvalue_network00(
            data.expand(settings.critic_ensemble, *data.batch_size),
            learner.loss.qvalue_network_params,
        )["state_action_value"]
        .squeeze(-1)
        .min(0)
        .values
    )
print(
    f"{run}: filling steps {int(filling.sum())}, Q min-ensemble mean {q.mean():.2f} "
    f"(median {q.median():.2f}), MC return mean {returns[filling].mean():.2f}"
)
