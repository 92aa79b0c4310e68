"""Hypothesis strategies shared by the fuzz tests: command lines that are valid, nearly valid, or garbage.

Nearly valid lines matter most: random bytes almost never get past the ID check, so the parser's later branches
(skill names, number tokens, argument counts) are only reached by lines built from plausible parts.
"""

from __future__ import annotations

from hypothesis import strategies as st

SKILLS = ("move_to", "move_joints", "move_rel_world", "move_rel_tool", "move_rel_joints", "break", "set_speed",
          "enable_air", "disable_air", "here", "hello", "stop", "signal", "sig", "wait_sig", "open_hand",
          "close_hand", "relax_hand")

ids = st.one_of(
    st.text("0123456789abcdef", min_size=8, max_size=8),
    st.text("0123456789abcdefABCDEFxyz", min_size=0, max_size=10),  # wrong lengths, upper case
    st.text(min_size=0, max_size=9),                                 # anything, non-ASCII included
)
skills = st.one_of(
    st.sampled_from(SKILLS),
    st.from_regex(r"[a-z][a-z0-9._]{0,16}", fullmatch=True),        # up to 2 over the 15-character limit
    st.text(min_size=0, max_size=8),
)
numbers = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6).map(lambda v: "%.3f" % v),
    st.integers(-1000, 1000).map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e5", "--1", "+-2", "1.2.3", "", " ", " 7 ", ".", "-.", ".5", "5.",
                     "0x10", "9" * 100, "1_000", "\u00bd", "\u0661"]),
    st.text("0123456789.+-eE ", max_size=12),
)
arg_lists = st.lists(numbers, max_size=8).map(",".join)


@st.composite
def near_lines(draw) -> bytes:
    """ID:SKILL[:ARGS] from plausible parts, sometimes with extra fields or stray separators."""
    parts = [draw(ids), draw(skills)]
    n_extra = draw(st.integers(0, 2))
    for _ in range(n_extra):
        parts.append(draw(arg_lists))
    text = ":".join(parts)
    if draw(st.booleans()):
        text = text.replace(":", draw(st.sampled_from([":", "::", ";", ": "])), 1)
    return text.encode("utf-8", "replace")


lines = st.one_of(near_lines(), st.binary(max_size=200), st.text(max_size=160).map(lambda t: t.encode()))
"""One line without delimiter (it may still contain CR or LF when drawn as raw bytes)."""
