"""Random small edits of a text, for loader fuzz tests (seeded by the caller's rng)."""
import random


def mutate(text: str, rng: random.Random, alphabet: str) -> str:
    """`text` with 1 to 4 characters deleted, inserted or replaced at random."""
    chars = list(text)
    for _ in range(rng.randint(1, 4)):
        pos = rng.randrange(len(chars))
        op = rng.random()
        if op < 0.4:
            del chars[pos]
        elif op < 0.7:
            chars.insert(pos, rng.choice(alphabet))
        else:
            chars[pos] = rng.choice(alphabet)
    return "".join(chars)
