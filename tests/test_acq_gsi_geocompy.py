"""Robocal's GSI codec against GeoComPy's GSI reader and writer (software nobody here wrote; issue 17 item 4)."""
from __future__ import annotations

import math

import pytest

from tests.dev_extra import require
from hypothesis import given, settings, strategies as st

from acq.drivers import gsi_codec as gsi
from tests.fakes.fuzz_targets import gsi_cross_check

gf = require("geocompy.gsi.gsiformat", "geocompy")


@settings(max_examples=400, deadline=None)
@given(st.binary(min_size=1, max_size=16))
def test_generated_blocks_read_the_same_both_ways(seed):
    gsi_cross_check(seed)


#: real GSI lines (totalopenstation sample data, GeoComPy test data; protocols.md §2.2)
REAL = [
    "110001+00000001 21.322+03496940 22.322+09364360 31..00+00030485 51..1.+0000+000 87..10+00001500 "
    "81..00+00515836 82..00+00525871 83..00+00003079 71....+00000001 32..10+00030333 ",
    "*110002+00000000GDEM5415 21.024+0000000003545100 22.024+0000000009117510 31...0+0000000000013825 "
    "51....+000000000017+000 87...0+0000000000001300 88...0+0000000000001324 ",
    "*11....+00000000000P0001 21.324+0000000024943030 22.324+0000000008336237 31..06+0000000000073493 "
    "51....+000000000000+000 87..16+0000000000000000 ",
    "110023+00000122 21.102+04392100 22.102+10354100 31..00+00004600 32..00+00004593 ",
]


@pytest.mark.parametrize("line", REAL)
def test_real_lines_read_the_same_as_geocompy(line):
    ours = {w.wi: w for w in gsi.parse_block(line)}
    theirs = gf.GsiBlock.parse(line, keep_unknowns=True)
    assert all(w.known for w in ours.values())
    assert ours[11].text() == theirs.value
    for wi, cls in ((21, gf.GsiHorizontalAngleWord), (22, gf.GsiVerticalAngleWord)):
        assert abs(ours[wi].angle_rad() - theirs.get_word(cls).value.asunit("rad")) < 1e-9
    assert abs(ours[31].length_m() - theirs.get_word(gf.GsiSlopeDistanceWord).value) < 1e-12


def test_characters_geocompy_refuses_are_read_here():
    """'/' in a point name makes GeoComPy drop the whole block; robocal keeps the name and the angles."""
    line = "110012+PT_4/7?A 21.102+17920860 22.102+07567500 "
    with pytest.raises(ValueError):
        gf.GsiBlock.parse(line, keep_unknowns=True)
    words = {w.wi: w for w in gsi.parse_block(line)}
    assert words[11].text() == "PT_4/7?A" and abs(words[21].angle_rad() - 179.2086 * math.pi / 200) < 1e-12
