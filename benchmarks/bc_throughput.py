"""Behaviour-cloning training throughput: ``train_bc`` vs the loop it replaced and a plain one.

Every path trains the same DANNet (s = 4 sensors, s' = all 7) with RAdam, batch 512,
lr 1e-3, MSE, on the same synthetic data, in one run:

- ``BCLoss on tensordicts``: the loop ``train_bc`` ran before (TorchRL's ``BCLoss`` on a
  tensordict batch gathered by index each step), the baseline of the speed-up;
- ``plain PyTorch loop``: the same training written directly against the modules;
- ``train_bc``: pilerl's loop (one contiguous tensor of normalised inputs, a row gather
  per step).

- ``train_bc, packed masks``: ``train_bc`` with ``dropout_masks="packed"``;
- ``train_bc, packed masks drawn ahead``: ``draw_packed_ahead=True`` (the same run as
  packed masks drawn in the step);
- ``train_bc as of e32a7b4``: ``train_bc``'s step before ``FlatRAdam`` (torch's RAdam
  step, advanced-index gathers), with torch's masks drawn in the step or ahead;
- ``train_bc, masks drawn ahead``: ``train_bc`` with ``draw_ahead=True`` (torch's masks
  drawn on a second thread, bit-identical).

Each path runs ``--repeats`` times, interleaved; the table gives the median wall time and
the ratios are medians of the per-round ratios (the machine may be shared). The ensemble
rows train ``--seeds`` members (``train_bc_ensemble``, ``torch.func``, in passes of
``MEMBERS_PER_PASS``), with packed dropout masks (now) and torch's ``bernoulli`` draws
(before), and give their cost in one-seed units (the median one-seed ``train_bc`` time of
the same run, torch's masks). ``--pass-sizes`` adds packed rows with other pass sizes.

    python benchmarks/bc_throughput.py --samples 51200 --epochs 1 --seeds 8 100

``--profile N...`` profiles ``--profile-steps`` ensemble steps of N members with each mask
draw instead (``torch.profiler``, the top entries by self CPU time); ``--masks-check K``
trains K seeds with each mask draw on the synthetic data (validation on a second draw of
it) and compares the validation losses per epoch (the two draws' distributions).

``--compile-check N`` trains N steps with ``torch.compile`` of the forward pass and loss
(inductor, CPU: needs a C++ compiler at run time) and eagerly, in the same process, and
reports the compile time, the step times and how far the results move.

``--paper`` measures the paper's schedule end to end instead: ``train_bc`` and the
``BCLoss`` loop for ``--epochs`` epochs each on a synthetic D_I-size dataset (709,368
samples), with ``--threads`` intra-op threads, per-epoch times, and the 150-epoch wall
time extrapolated from the median epoch (labelled as such), plus whether both paths end
with bit-identical weights.

    python benchmarks/bc_throughput.py --paper --epochs 3 --threads 2

``--paper --epochs 150 --train-bc-only`` runs the whole schedule with ``train_bc`` alone and
reports its measured wall time; ``--dropout-masks packed`` trains it with packed masks,
``--draw-ahead`` with torch's masks drawn ahead on a second thread.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import time
from contextlib import nullcontext

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402
import torch.nn.functional as F  # noqa: E402
from tensordict import TensorDict  # noqa: E402
from torchrl.objectives import BCLoss  # noqa: E402

from pilerl.policies import make_actor  # noqa: E402
from pilerl.training import BCSettings, train_bc, train_bc_ensemble  # noqa: E402
from pilerl.training.draw_ahead import masks_ahead  # noqa: E402
from pilerl.training.dropout_masks import dropout_masks  # noqa: E402
from pilerl.training.ensemble import MEMBERS_PER_PASS  # noqa: E402

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
ALL = SENSORS + ["boom_pressure", "bucket_pressure", "pump_angle"]
STATS = {
    "sensors": {k: {"mean": 0.0, "std": 1.0, "min": -5.0, "max": 5.0} for k in ALL},
    "action": {"mean": [0.0] * 3, "std": [1.0] * 3, "min": [-1.0] * 3, "max": [1.0] * 3},
    "n_samples": 1,
}
PAPER_SAMPLES, PAPER_EPOCHS = 709_368, 150
BASELINES = {  # --paper's "before" loop
    "bcloss": "BCLoss on tensordicts (before)",
    "previous": "train_bc as of e32a7b4 (torch's RAdam step)",
}
BATCH = 512


def dataset(n: int, seed: int = 0) -> TensorDict:
    generator = torch.Generator().manual_seed(seed)
    sensors = {k: torch.randn(n, 1, generator=generator) for k in ALL}
    action = torch.tanh(sensors["drive_pressure"] - sensors["telescope_pressure"]).expand(n, 3)
    return TensorDict({**sensors, "action": action.clone()}, [n])


def fresh_actor():
    torch.manual_seed(0)
    return make_actor("dannet", sensors=SENSORS, stats=STATS, attention_sensors=ALL)


def bcloss_loop(
    actor, data: TensorDict, settings: BCSettings, epoch_times: list[float], *, say=None
):
    """``train_bc``'s gradient loop before the contiguous path (the speed-up's baseline);
    ``say`` (if given) is called with a line per epoch."""
    policy = actor.module
    torch.manual_seed(settings.seed)
    data = data.select(*policy.in_keys, "action")
    optimizer = torch.optim.RAdam(policy.parameters(), lr=settings.learning_rate)
    loss_module = BCLoss(actor, loss_function="mse")
    n = data.batch_size[0]
    for epoch in range(settings.epochs):
        start = time.perf_counter()
        policy.train()
        generator = torch.Generator().manual_seed(settings.seed * 1_000_003 + epoch)
        order, total = torch.randperm(n, generator=generator), 0.0
        for i in range(0, n, settings.batch_size):
            batch = data[order[i : i + settings.batch_size]]
            loss = loss_module(batch)["loss_bc"]
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * batch.batch_size[0]
        epoch_times.append(time.perf_counter() - start)
        if say is not None:
            say(f"BCLoss loop: epoch {epoch + 1} took {epoch_times[-1]:.1f} s")
    return actor


def previous_train_bc(
    actor, data: TensorDict, settings: BCSettings, epoch_times: list[float], *, draw_ahead=False,
    say=None,
):  # fmt: skip
    """``train_bc``'s gradient loop as of e32a7b4 (before ``FlatRAdam`` and ``index_select``):
    torch's RAdam step, one parameter after another, and advanced-index row gathers; with
    ``draw_ahead``, torch's masks drawn ahead as ``train_bc`` draws them."""
    policy = actor.module
    torch.manual_seed(settings.seed)
    data = data.select(*policy.in_keys, "action")
    optimizer = torch.optim.RAdam(policy.parameters(), lr=settings.learning_rate)
    inputs, attention_inputs = policy.controller_inputs(data)
    target, n = data["action"], data.batch_size[0]
    controller = policy.controller
    ahead = (
        masks_ahead(controller, lambda: controller(inputs[:1], attention_inputs[:1]))
        if draw_ahead
        else nullcontext(None)
    )
    with dropout_masks(policy, settings.dropout_masks or "bernoulli"), ahead as feed:
        for epoch in range(settings.epochs):
            start = time.perf_counter()
            policy.train()
            generator = torch.Generator().manual_seed(settings.seed * 1_000_003 + epoch)
            order = torch.randperm(n, generator=generator)
            starts = range(0, n, settings.batch_size)
            if feed is not None:
                feed.start_epoch([len(order[i : i + settings.batch_size]) for i in starts])
            for i in starts:
                rows = order[i : i + settings.batch_size]
                if feed is not None:
                    feed.next_step()
                predicted = controller(inputs[rows], attention_inputs[rows]).action
                loss = F.mse_loss(predicted, target[rows], reduction="none").mean()
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                float(loss.detach())
            if feed is not None:
                feed.end_epoch()
            epoch_times.append(time.perf_counter() - start)
            if say is not None:
                say(f"previous train_bc: epoch {epoch + 1} took {epoch_times[-1]:.1f} s")
    return actor


def plain_loop(data: TensorDict, epochs: int) -> None:
    """The same training written directly against the modules."""
    policy = fresh_actor().module
    optimizer = torch.optim.RAdam(policy.parameters(), lr=1e-3)
    readings = torch.cat([data[k] for k in policy.in_keys], -1)
    target = data["action"]
    n = data.batch_size[0]
    for epoch in range(epochs):
        policy.train()
        order = torch.randperm(n, generator=torch.Generator().manual_seed(epoch))
        for i in range(0, n, BATCH):
            idx = order[i : i + BATCH]
            s, s_att = policy.normalized_inputs(readings[idx])
            loss = ((policy.controller(s, s_att).action - target[idx]) ** 2).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()


def timed(call) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def throughput(args: argparse.Namespace) -> None:
    data = dataset(args.samples)
    settings = BCSettings(epochs=args.epochs, batch_size=BATCH)
    packed = BCSettings(epochs=args.epochs, batch_size=BATCH, dropout_masks="packed")
    bernoulli = BCSettings(epochs=args.epochs, batch_size=BATCH, dropout_masks="bernoulli")
    paths = {
        "BCLoss on tensordicts (before)": lambda: bcloss_loop(fresh_actor(), data, settings, []),
        "plain PyTorch loop": lambda: plain_loop(data, args.epochs),
        "train_bc as of e32a7b4 (torch's RAdam step)": lambda: previous_train_bc(
            fresh_actor(), data, settings, []
        ),
        "train_bc as of e32a7b4, masks drawn ahead": lambda: previous_train_bc(
            fresh_actor(), data, settings, [], draw_ahead=True
        ),
        "pilerl train_bc": lambda: train_bc(fresh_actor(), data, None, settings, progress=False),
        "pilerl train_bc, packed masks": lambda: train_bc(
            fresh_actor(), data, None, packed, progress=False
        ),
        "pilerl train_bc, masks drawn ahead": lambda: train_bc(
            fresh_actor(), data, None, settings, progress=False, draw_ahead=True
        ),
        "pilerl train_bc, packed masks drawn ahead": lambda: train_bc(
            fresh_actor(), data, None, packed, progress=False, draw_packed_ahead=True
        ),
    }
    config = fresh_actor().module.config

    def ensemble(seeds: int, masks: BCSettings, per_pass: int = MEMBERS_PER_PASS):
        return lambda: train_bc_ensemble(
            config, list(range(seeds)), data, None, masks, progress=False,
            members_per_pass=per_pass,
        )  # fmt: skip

    for seeds in args.seeds:
        paths[f"{seeds}-seed ensemble, torch's masks (before)"] = ensemble(seeds, bernoulli)
        paths[f"{seeds}-seed ensemble, packed masks"] = ensemble(seeds, packed)
        for size in args.pass_sizes:
            if size < seeds and size != MEMBERS_PER_PASS:
                paths[f"{seeds}-seed ensemble, packed masks, passes of {size}"] = ensemble(
                    seeds, packed, size
                )
    warm_up = dataset(2 * BATCH)
    bcloss_loop(fresh_actor(), warm_up, BCSettings(epochs=1), [])
    train_bc(fresh_actor(), warm_up, None, BCSettings(epochs=1), progress=False)
    train_bc_ensemble(config, [0, 1], warm_up, None, BCSettings(epochs=1), progress=False)
    rounds: dict[str, list[float]] = {name: [] for name in paths}
    for _ in range(args.repeats):
        for name, call in paths.items():
            rounds[name].append(timed(call))

    def ratio(a: str, b: str) -> float:
        return float(np.median([x / y for x, y in zip(rounds[a], rounds[b], strict=True)]))

    total = args.samples * args.epochs
    print(
        f"DANNet, batch {BATCH}, RAdam, {args.samples:,} samples x {args.epochs} epochs, "
        f"{torch.get_num_threads()} thread(s), median of {args.repeats} rounds\n"
    )
    print("| path | wall s | samples/s (all seeds) | vs plain loop | vs before | one-seed units |")
    print("|---|---:|---:|---:|---:|---:|")
    for name in paths:
        seeds = int(name.split("-")[0]) if "ensemble" in name else 1
        wall = float(np.median(rounds[name]))
        units = ratio(name, "pilerl train_bc")
        print(
            f"| {name} | {wall:.2f} | {total / wall * seeds:,.0f} | "
            f"{ratio('plain PyTorch loop', name):.2f} | "
            f"{ratio('BCLoss on tensordicts (before)', name):.2f} | {units:.1f} |"
        )
    print(
        "\nvs plain loop / vs before: speed ratio (> 1 = faster); one-seed units: wall time "
        "over one train_bc run (for an ensemble: what its seeds cost together)"
    )
    for now, before in (
        ("pilerl train_bc", "train_bc as of e32a7b4 (torch's RAdam step)"),
        ("pilerl train_bc, masks drawn ahead", "train_bc as of e32a7b4, masks drawn ahead"),
    ):
        print(f"{now} vs {before}: {ratio(before, now):.2f}x (median of the rounds' ratios)")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory of this run: {peak_mb:,.0f} MB")


def paper_schedule(args: argparse.Namespace) -> None:
    data = dataset(PAPER_SAMPLES)
    settings = BCSettings(epochs=args.epochs, batch_size=BATCH, dropout_masks=args.dropout_masks)
    warm_up = dataset(2 * BATCH)
    train_bc(fresh_actor(), warm_up, None, BCSettings(epochs=1), progress=False)
    before, before_epochs, before_wall = None, [], float("nan")
    packed = args.dropout_masks == "packed"
    # e32a7b4 drew torch's masks ahead only: its packed masks are drawn in the step
    previous_ahead = args.draw_ahead and not packed
    if not args.train_bc_only:
        say = lambda line: print(line, flush=True)  # noqa: E731
        if args.baseline == "previous":

            def baseline(actor, data, settings, times, say=None):
                return previous_train_bc(
                    actor, data, settings, times, draw_ahead=previous_ahead, say=say
                )
        else:
            baseline = bcloss_loop
        baseline(fresh_actor(), warm_up, BCSettings(epochs=1), [])
        start = time.perf_counter()
        before = baseline(fresh_actor(), data, settings, before_epochs, say=say)
        before_wall = time.perf_counter() - start

    class EpochClock:
        """A logger that records when each epoch's row is logged."""

        def __init__(self) -> None:
            self.marks = [time.perf_counter()]

        def log_scalar(self, name: str, value: float, step: int) -> None:
            self.marks.append(time.perf_counter())
            print(
                f"train_bc: epoch {step} took {self.marks[-1] - self.marks[-2]:.1f} s", flush=True
            )

    clock = EpochClock()
    start = time.perf_counter()
    after, _ = train_bc(
        fresh_actor(), data, None, settings, logger=clock, progress=False,
        draw_ahead=args.draw_ahead and not packed, draw_packed_ahead=args.draw_ahead and packed,
    )  # fmt: skip
    after_wall = time.perf_counter() - start
    after_epochs = list(np.diff(clock.marks))
    same = before is not None and all(
        torch.equal(a, b)
        for a, b in zip(
            before.module.state_dict().values(), after.module.state_dict().values(), strict=True
        )
    )
    print(
        f"Paper schedule, DANNet, batch {BATCH}, {PAPER_SAMPLES:,} samples, {args.epochs} of "
        f"{PAPER_EPOCHS} epochs measured, {torch.get_num_threads()} thread(s), train_bc's "
        f"dropout masks: {args.dropout_masks}{', drawn ahead' if args.draw_ahead else ''}\n"
    )
    print("| path | epochs s (median, min-max) | measured wall s | 150 epochs |")
    print("|---|---|---:|---:|")
    ahead = ", drawn ahead" if args.draw_ahead else ""
    rows = [(f"pilerl train_bc ({args.dropout_masks} masks{ahead})", after_epochs, after_wall)]
    if before is not None:
        name = BASELINES[args.baseline] + (ahead if previous_ahead else "")
        rows.insert(0, (name, before_epochs, before_wall))
    for name, epochs, wall in rows:
        listed = f"{np.median(epochs):.1f} ({min(epochs):.1f}-{max(epochs):.1f})"
        if len(epochs) == PAPER_EPOCHS:
            whole = f"{wall / 60:.1f} min (measured)"
        else:
            whole = f"{float(np.median(epochs)) * PAPER_EPOCHS / 60:.1f} min (extrapolated)"
        print(f"| {name} | {listed} | {wall:.1f} | {whole} |")
    if before is None:
        return
    per_epoch = [b / a for a, b in zip(after_epochs, before_epochs, strict=True)]
    print(
        f"\nper-epoch speed-up of train_bc over the {BASELINES[args.baseline]} (median over "
        f"epochs): "
        f"{np.median(per_epoch):.2f}x; final weights bit-identical: {same}"
    )


def profile_ensemble(args: argparse.Namespace) -> None:
    """The top entries (self CPU) of ``--profile-steps`` ensemble steps, per mask draw."""
    from torch.profiler import ProfilerActivity, profile

    data = dataset(BATCH * args.profile_steps)
    config = fresh_actor().module.config
    for members in args.profile:
        for masks in ("bernoulli", "packed"):
            settings = BCSettings(epochs=1, batch_size=BATCH, dropout_masks=masks)
            seeds = list(range(members))
            train_bc_ensemble(config, seeds, dataset(2 * BATCH), None, settings, progress=False)
            with profile(activities=[ProfilerActivity.CPU]) as prof:
                start = time.perf_counter()
                train_bc_ensemble(
                    config, seeds, data, None, settings, progress=False, members_per_pass=members
                )
                wall = time.perf_counter() - start
            print(
                f"\n{members} members in one pass, {masks} masks, {args.profile_steps} steps "
                f"of batch {BATCH} (with building the members), {wall:.2f} s under the "
                "profiler; top entries by self CPU time:\n"
            )
            print(
                prof.key_averages().table(
                    sort_by="self_cpu_time_total", row_limit=args.profile_rows,
                    max_name_column_width=45,
                )
            )  # fmt: skip


def masks_check(args: argparse.Namespace) -> None:
    """Validation losses of ``--masks-check`` seeds trained with each mask draw."""
    data, validation = dataset(args.samples), dataset(args.samples // 4, seed=1)
    config = fresh_actor().module.config
    seeds = list(range(args.masks_check))
    losses = {}
    for masks in ("bernoulli", "packed"):
        settings = BCSettings(epochs=args.epochs, batch_size=BATCH, dropout_masks=masks)
        result = train_bc_ensemble(config, seeds, data, validation, settings, progress=False)
        losses[masks] = result.validation_loss
    print(
        f"DANNet, batch {BATCH}, {args.samples:,} samples x {args.epochs} epochs, "
        f"{len(seeds)} seeds per mask draw (train_bc_ensemble), validation on "
        f"{args.samples // 4:,} other samples\n"
    )
    print("| epoch | bernoulli: mean +- std | packed: mean +- std | difference / its s.e. |")
    print("|---:|---:|---:|---:|")
    for epoch in range(args.epochs):
        a, b = losses["bernoulli"][:, epoch], losses["packed"][:, epoch]
        welch = (b.mean() - a.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b))
        print(
            f"| {epoch + 1} | {a.mean():.3e} +- {a.std(ddof=1):.2e} | "
            f"{b.mean():.3e} +- {b.std(ddof=1):.2e} | {welch:+.2f} |"
        )
    print("\n(Welch's t: |t| < 2 is what two samples of one distribution give 95% of the time)")


def compile_check(args: argparse.Namespace) -> None:
    """``torch.compile`` (inductor, CPU) of the controller's forward and MSE, the backward
    through AOTAutograd, with torch's masks drawn ahead and handed in: compile time, the
    time of a step against eager in the same process, and how far the losses and weights
    of ``--compile-check`` steps move from eager's (another code generator: other bits)."""
    compiler = os.environ.get("CXX") or shutil.which("g++") or shutil.which("c++")
    if compiler is None or shutil.which(compiler) is None:
        raise SystemExit(
            "--compile-check: torch.compile's CPU backend (inductor) compiles C++ at run time "
            "and no C++ compiler was found (set CXX or install g++)"
        )
    steps = args.compile_check
    data = dataset(BATCH * steps + 248)  # and a short last batch, as an epoch of D_I has

    def run(compiled: bool):
        policy = fresh_actor().module
        torch.manual_seed(0)
        optimizer = torch.optim.RAdam(policy.parameters(), lr=1e-3)
        inputs, attention_inputs = policy.controller_inputs(data.select(*policy.in_keys))
        target, controller = data["action"], policy.controller

        def loss_of(s, s_att, y):
            return F.mse_loss(controller(s, s_att).action, y, reduction="none").mean()

        loss_fn = torch.compile(loss_of, dynamic=False) if compiled else loss_of
        order = torch.randperm(len(inputs), generator=torch.Generator().manual_seed(0))
        starts = list(range(0, len(order), BATCH))
        losses, times = [], []
        policy.train()
        with masks_ahead(controller, lambda: controller(inputs[:1], attention_inputs[:1])) as feed:
            feed.start_epoch([len(order[i : i + BATCH]) for i in starts])
            for i in starts:
                start = time.perf_counter()
                rows = order[i : i + BATCH]
                feed.next_step()
                loss = loss_fn(inputs[rows], attention_inputs[rows], target[rows])
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                losses.append(float(loss.detach()))
                times.append(time.perf_counter() - start)
            feed.end_epoch()
        return losses, policy.state_dict(), times

    compiled_losses, compiled_weights, compiled_times = run(True)
    losses, weights, times = run(False)
    loss_error = max(abs(a - b) / abs(a) for a, b in zip(losses, compiled_losses, strict=True))
    weight_error = max(float((weights[k] - compiled_weights[k]).abs().max()) for k in weights)
    same = all(torch.equal(weights[k], compiled_weights[k]) for k in weights)
    print(
        f"DANNet, batch {BATCH}, {steps} steps and a last batch of 248 rows, torch's masks drawn "
        f"ahead, 1 thread; torch.compile(dynamic=False) of forward + MSE (backward by "
        f"AOTAutograd), C++ compiler {compiler}\n"
    )
    print("| path | first step s (compiles) | last batch's first step s | step ms (median) |")
    print("|---|---:|---:|---:|")
    for name, t in (("eager", times), ("torch.compile", compiled_times)):
        print(f"| {name} | {t[0]:.2f} | {t[-1]:.2f} | {1e3 * np.median(t[1:-1]):.2f} |")
    ratio = np.median(compiled_times[1:-1]) / np.median(times[1:-1])
    print(
        f"\nstep time compiled / eager: {ratio:.2f}"
        f"; bit-identical weights: {same}; largest relative loss difference "
        f"{loss_error:.1e}, largest weight difference {weight_error:.1e} after {steps + 1} steps"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=51_200)
    parser.add_argument("--epochs", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seeds", type=int, nargs="*", default=[8])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--paper", action="store_true", help="the paper's schedule, see above")
    parser.add_argument(
        "--train-bc-only",
        action="store_true",
        help="with --paper: time train_bc alone (the whole 150 epochs in one run)",
    )
    parser.add_argument(
        "--dropout-masks",
        choices=["bernoulli", "packed"],
        default="bernoulli",
        help="with --paper: train_bc's dropout masks",
    )
    parser.add_argument(
        "--draw-ahead",
        action="store_true",
        help="with --paper: train_bc(draw_ahead=True), with packed masks draw_packed_ahead",
    )
    parser.add_argument(
        "--baseline",
        choices=sorted(BASELINES),
        default="bcloss",
        help="with --paper: the loop train_bc is compared with (previous: train_bc's step as "
        "of e32a7b4, torch's RAdam, with --draw-ahead and --dropout-masks as train_bc's)",
    )
    parser.add_argument(
        "--pass-sizes", type=int, nargs="*", default=[], help="more ensemble pass sizes"
    )
    parser.add_argument("--profile", type=int, nargs="*", default=[], help="ensemble sizes")
    parser.add_argument("--profile-steps", type=int, default=10)
    parser.add_argument("--profile-rows", type=int, default=15)
    parser.add_argument("--masks-check", type=int, default=0, help="seeds per mask draw")
    parser.add_argument(
        "--compile-check", type=int, default=0, help="steps of torch.compile against eager"
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    if args.compile_check:
        compile_check(args)
    elif args.profile:
        profile_ensemble(args)
    elif args.masks_check:
        masks_check(args)
    elif args.paper:
        paper_schedule(args)
    else:
        throughput(args)


if __name__ == "__main__":
    main()
