"""Nothing moved: every contract channel, bit for bit, against the stored digests.

The catalogue (tests/digests.py) covers the teapot, the stress scenes, the rational and
trimmed samples and the impeller at every criterion x split x precision. A change that is
meant to move results regenerates the store on purpose (`python tests/digests.py --write`).
"""
import json
import os
import subprocess
import sys

import pytest

import digests as D
import scenes as S

STORED = json.loads(D.STORE.read_text())

# Cheap enough to run with NUMBA_DISABLE_JIT=1 (a few seconds each): the interpreted kernels
# must report the bits the compiled ones stored.
INTERPRETED = [("stress/teapot +1e4", "mantissa/length/f32"), ("stress/teapot +1e4", "adaptive/cross/f64"),
               ("sphere", "adaptive/cross/f64")]


@pytest.mark.parametrize("name", list(D.catalogue()))
def test_channels_bit_identical(name):
    got = D.scene_digests(name)
    if got is None:
        pytest.skip(f"{name}: not available on this machine")
    expected = STORED[name]
    moved = [f"{key} {channel}" for key, channels in expected.items() for channel, digest in channels.items()
             if got[key][channel] != digest]
    assert not moved, f"{name}: {len(moved)} channels moved: " + ", ".join(moved[:12])
    assert set(got) == set(expected)


@pytest.mark.interpreted
@pytest.mark.parametrize("name, key", INTERPRETED)
def test_one_variant_bit_identical(name, key):
    """One variant of one scene: what test_channels_bit_identical checks, small enough to run
    interpreted (tests/test_interpreted.py)."""
    opts = dict(D.variants())[key]
    got = D.variant_digests(name, opts)
    moved = [channel for channel, digest in STORED[name][key].items() if got[channel] != digest]
    assert not moved, f"{name} {key}: channels moved: {', '.join(moved)}"


BLAS_CORES = ("Haswell", "SkylakeX")  # OpenBLAS kernels of different widths (the AVX2 and AVX-512 ones)
DIGEST_ONE = """
import json, sys
sys.path.insert(0, "tests")
import digests as D
print(json.dumps(D.variant_digests(sys.argv[1], dict(D.variants())["float/length/f64"])))
"""


@pytest.mark.parametrize("name", ["stress/bottom apex", "impeller"])
def test_digests_do_not_depend_on_the_blas_kernels(name):
    """The same bits whichever kernels OpenBLAS picks for this CPU (tracer/fixed_order.py); a
    kernel this CPU lacks falls back to an older one, which is a check all the same."""
    if D._scene(name)[0] is None:
        pytest.skip(f"{name}: not available on this machine")
    outs = []
    for core in BLAS_CORES:
        env = {**os.environ, "OPENBLAS_CORETYPE": core}
        proc = subprocess.run([sys.executable, "-c", DIGEST_ONE, name], cwd=S.REPO, env=env, capture_output=True,
                              text=True, timeout=900)
        assert proc.returncode == 0, proc.stderr[-3000:]
        outs.append(json.loads(proc.stdout.splitlines()[-1]))
    assert outs[0] == outs[1]
    assert outs[0] == STORED[name]["float/length/f64"]
