"""Nothing moved: every contract channel, bit for bit, against the stored digests.

The catalogue (tests/digests.py) covers the teapot, the stress scenes, the rational and
trimmed samples and the impeller at every criterion x split x precision. A change that is
meant to move results regenerates the store on purpose (`python tests/digests.py --write`).
"""
import json

import pytest

import digests as D

STORED = json.loads(D.STORE.read_text())


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
