"""The demo's sending virtual bus (sim.emulate.can_node.SenderVirtualBus) delivers what python-can's virtual bus
delivers: the same frames in order, each receiver its own message object, flagged received, on the channel."""
from __future__ import annotations

import uuid

import can
import pytest

from sim.emulate.can_node import SenderVirtualBus


def _frames():
    return [can.Message(arbitration_id=0x100 + k, data=bytes(range(k, k + 8)), is_extended_id=False)
            for k in range(5)]


def _received(sender_cls):
    ch = f"test-sender-{uuid.uuid4().hex[:8]}"
    rx1 = can.Bus(interface="virtual", channel=ch)
    rx2 = can.Bus(interface="virtual", channel=ch)
    tx = sender_cls(channel=ch)
    try:
        sent = _frames()
        for m in sent:
            tx.send(m)
        got = [[b.recv(1.0) for _ in sent] for b in (rx1, rx2)]
        assert tx.recv(0.0) is None                      # no own messages unless asked
        return sent, got
    finally:
        for b in (rx1, rx2, tx):
            b.shutdown()


def test_sender_bus_delivers_like_python_can_virtual_bus():
    sent, got = _received(SenderVirtualBus)
    _, ref = _received(lambda channel: can.Bus(interface="virtual", channel=channel))
    for mine, theirs in zip(got, ref):
        for m, r, s in zip(mine, theirs, sent):
            assert m is not s and m.data is not s.data and m is not theirs
            assert (m.arbitration_id, bytes(m.data), m.dlc, m.is_extended_id, m.is_rx) == \
                   (r.arbitration_id, bytes(r.data), r.dlc, r.is_extended_id, r.is_rx)
            assert m.channel.startswith("test-sender-") and r.channel.startswith("test-sender-")
            assert m.is_rx and bytes(m.data) == bytes(s.data)
    assert got[0][0] is not got[1][0]                    # each receiver its own copy


def test_sender_bus_closed_raises():
    tx = SenderVirtualBus(channel=f"test-sender-{uuid.uuid4().hex[:8]}")
    tx.shutdown()
    with pytest.raises(can.CanOperationError):
        tx.send(_frames()[0])
