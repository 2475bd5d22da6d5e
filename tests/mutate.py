"""Random damage to a text, for loader fuzz tests (seeded by the caller's rng)."""
import random
import re


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


NUMBER = re.compile(r"[0-9]+\.?[0-9]*(?:[eE][-+]?[0-9]+)?")
NON_FINITE = ("nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e400", "infinity ")
HUGE = ("1" * 5000, "9" * 100_000, "x" * 100_000, "1." + "0" * 100_000)
NON_ASCII_DIGITS = "\u0661\u0663\u06f4\uff15\u00b2\U0001d7d9"   # Arabic-Indic, fullwidth, ...
ODD_SPACES = ("\u00a0", "\u2003", "\x1c", "\x85")                # str.split() splits at these
JUNK = ("junk\n", "7 7 7\n", "\x00\xff", "#c\n1 1\n", "\n" + "9 " * 5000)
KINDS = ("truncate", "flip", "non_finite", "huge", "digits", "underscore", "spaces", "junk",
         "edit")


def damage(text: str, rng: random.Random, kind: str, alphabet: str = "0123456789 -.,\n#eE") -> bytes:
    """`text` damaged in one of the ways of KINDS (see the names), as the bytes of a file."""
    numbers = [m.span() for m in NUMBER.finditer(text)] or [(0, 0)]
    a, b = rng.choice(numbers)
    if kind == "truncate":
        return text.encode()[:rng.randrange(len(text.encode()))]
    if kind == "flip":
        data = bytearray(text.encode())
        data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        return bytes(data)
    if kind == "non_finite":
        out = text[:a] + rng.choice(NON_FINITE) + text[b:]
    elif kind == "huge":
        out = text[:a] + rng.choice(HUGE) + text[b:]
    elif kind == "digits":
        out = text[:a] + rng.choice(NON_ASCII_DIGITS) + text[a + 1:]
    elif kind == "underscore":
        out = text[:a] + text[a:b][:1] + "_" + text[a:b][1:] + (text[b:] if b > a else "0" + text[b:])
    elif kind == "spaces":
        spaces = [i for i, c in enumerate(text) if c == " "] or [0]
        i = rng.choice(spaces)
        out = text[:i] + rng.choice(ODD_SPACES) + text[i + 1:]
    elif kind == "junk":
        out = text + rng.choice(JUNK)
    else:
        out = mutate(text, rng, alphabet)
    return out.encode("utf-8", "surrogatepass")
