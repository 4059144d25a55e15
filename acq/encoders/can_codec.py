"""The tap's CAN frames, defined in the shipped DBC (``puma_tap.dbc``) and decoded with cantools.  Pure.

Why a DBC: the frame layout is then a document other tools read too (candump + cantools, SavvyCAN, a vendor tool),
and the decoder cannot drift from it.
"""
from __future__ import annotations

from functools import lru_cache
from importlib import resources

import cantools

DBC_NAME = "puma_tap.dbc"
STATUS_ID = 0x103
DATA_IDS = {0x100: 0, 0x101: 2, 0x102: 4}          # frame id -> first joint (0-based)


@lru_cache(maxsize=None)
def load_dbc():
    text = (resources.files("acq.encoders") / DBC_NAME).read_text(encoding="ascii")
    return cantools.database.load_string(text, database_format="dbc")


#: distinct data frames a codec keeps decoded (a robot holding still repeats its three data frames in every sample of
#: an encoder window; a moving one fills the memo, which then starts again)
MEMO_FRAMES = 4096


class TapCanCodec:
    """Decode (arbitration id, data) of a tap frame; None for frames that are not the tap's."""

    def __init__(self):
        db = load_dbc()
        self._messages = {m.frame_id: m for m in db.messages}
        #: the DBC's frame ids: the frames of the tap
        self.frame_ids = frozenset(self._messages)
        self._status = self._messages[STATUS_ID]
        self._data = {fid: (self._messages[fid], first,
                            (f"J{first + 1}_Counts", f"J{first + 2}_Counts")) for fid, first in DATA_IDS.items()}
        self._memo: dict[tuple[int, bytes], tuple[int, tuple[int, int]]] = {}

    def is_tap_frame(self, arbitration_id: int) -> bool:
        return arbitration_id in self.frame_ids

    def decode_status(self, data: bytes) -> tuple[int, int, int, int]:
        v = self._status.decode(data, decode_choices=False, scaling=False)
        return int(v["Seq"]), int(v["Timestamp_us"]), int(v["Flags"]), int(v["PotValid"])

    def decode_data(self, arbitration_id: int, data: bytes) -> tuple[int, tuple[int, int]]:
        """(first joint, its two counts).  Each distinct frame is decoded by cantools once and kept (a decoding is a
        pure function of the id and the bytes; the tap sends the same three data frames for every sample of a pose,
        ten to a hundred times): the demo's 6,630 data frames cost 660 decodings."""
        key = (arbitration_id, data)
        got = self._memo.get(key)
        if got is None:
            got = self._decode_data(arbitration_id, data)
            if len(self._memo) >= MEMO_FRAMES:
                self._memo.clear()
            self._memo[key] = got
        return got

    def _decode_data(self, arbitration_id: int, data: bytes) -> tuple[int, tuple[int, int]]:
        msg, first, (a, b) = self._data[arbitration_id]
        v = msg.decode(data, decode_choices=False, scaling=False)
        return first, (int(v[a]), int(v[b]))

    def encode(self, name: str, values: dict) -> tuple[int, bytes]:
        """For tools and tests (the emulator packs its own bytes)."""
        msg = load_dbc().get_message_by_name(name)
        return msg.frame_id, bytes(msg.encode(values))
