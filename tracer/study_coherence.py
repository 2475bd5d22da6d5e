"""The study's coherence series (tracer/study.py): which coherence setting is fastest is measured on
the study's own rays, not taken from the bench's tables.

For each criterion and precision a Trial traces the plain setting (1x1 rays through the BVH, no
cache) and every candidate setting at the criterion's trial parameter: each once untimed (compiles,
builds), then ROUNDS rounds in which every setting is traced once in turn (so a slow spell of the
machine falls on all of them), CPU time with one render thread as every psrt point. The candidate
of least median time is chosen for that criterion's coherence series, even where the plain setting
is faster (the speed-up then reads under 1). The rays are the study's own, at the study's size:
bundles share work between neighbouring pixels, so a reduced image would change what is measured.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .options import ACCELS, BUNDLES, PLAIN, Options

# Candidates, each a '+'-joined spec: a bundle (columns x rows), 'cache', an accelerator, 'mailbox'.
CANDIDATES = ("4x4", "8x8", "4x4+cache", "8x8+cache", "grid+mailbox")
ROUNDS = 3
# Where each criterion is tried: its default (adaptive, mantissa), or the middle of its sweep (fixed,
# as a fraction of the scene's size; study.FIXED_FRACTIONS).
TRIAL_PARAMETERS = {"float": None, "fixed": 1e-4, "adaptive": Options().pixel_fraction,
                    "mantissa": Options().mantissa_ulps}


def settings(spec: str) -> dict:
    """The option fields of a candidate spec ('8x8+cache', 'grid+mailbox'); ValueError naming the spec."""
    out = {}
    for token in spec.split("+"):
        if token in BUNDLES:
            out["bundle"] = token
        elif token in ("cache", "mailbox"):
            out[token] = True
        elif token in ACCELS:
            out["accel"] = token
        else:
            raise ValueError(f"coherence setting {spec!r}: {token!r} is none of the bundles "
                             f"{', '.join(BUNDLES)}, 'cache', 'mailbox' or the structures {', '.join(ACCELS)}")
    accel = out.get("accel", "bvh")
    if out.get("bundle", "1x1") != "1x1" and accel != "bvh":
        raise ValueError(f"coherence setting {spec!r}: bundles go through the BVH only")
    if out.get("mailbox") and accel == "bvh":
        raise ValueError(f"coherence setting {spec!r}: the mailbox is for the kd-tree and the grid")
    if all(PLAIN[k] == v for k, v in out.items()):
        raise ValueError(f"coherence setting {spec!r} is the plain setting, which is always measured")
    return out


@dataclass(frozen=True)
class Trial:
    """The timed comparison for one criterion and precision: `opts` the plain setting at the trial
    parameter (one render thread), `candidates` the specs, `rounds` the timed rounds."""

    criterion: str
    precision: str
    parameter: float | None
    opts: Options
    candidates: tuple
    rounds: int = ROUNDS

    @property
    def label(self) -> str:
        return f"coherence trial {self.criterion} {self.precision}"


def trials(sweep_options: dict, precisions, base: Options, candidates=CANDIDATES, rounds: int = ROUNDS) -> list:
    """A Trial per precision and criterion; sweep_options[criterion](parameter) gives the criterion's
    option fields at a parameter (study.sweep_options)."""
    base = base.with_(threads=1, **PLAIN)
    return [Trial(c, p, TRIAL_PARAMETERS[c],
                  base.with_(criterion=c, precision=p, **sweep_options[c](TRIAL_PARAMETERS[c])),
                  tuple(candidates), rounds)
            for p in precisions for c in TRIAL_PARAMETERS]


def run_trial(trace_seconds, trial: Trial) -> dict:
    """The trial's figures: median CPU seconds of every setting ('plain' first), the chosen candidate
    and the plain setting's time over the chosen one's. trace_seconds(opts) traces the study's rays
    with opts and returns its CPU seconds."""
    configs = [("plain", trial.opts)] + [(c, trial.opts.with_(**settings(c))) for c in trial.candidates]
    for _, opts in configs:
        trace_seconds(opts)  # untimed: compiles, builds
    times = {label: [] for label, _ in configs}
    for _ in range(trial.rounds):
        for label, opts in configs:
            times[label].append(trace_seconds(opts))
    seconds = {label: float(np.median(t)) for label, t in times.items()}
    chosen = min(trial.candidates, key=seconds.get)
    return {"criterion": trial.criterion, "precision": trial.precision, "parameter": trial.parameter,
            "seconds": seconds, "chosen": chosen, "speedup": seconds["plain"] / seconds[chosen]}
