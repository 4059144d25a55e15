"""The demo's sending virtual bus (sim.emulate.can_node.SenderVirtualBus) delivers what python-can's virtual bus
delivers: the same frames in order, each of several receivers its own message object, flagged received, on the
channel; a lone receiver the sent object itself (the sender never touches it again), with the same fields."""
from __future__ import annotations

import uuid

import can
import pytest

from sim.emulate.can_node import SenderVirtualBus


def _frames():
    return [can.Message(arbitration_id=0x100 + k, data=bytes(range(k, k + 8)), is_extended_id=False)
            for k in range(5)]


def _received(sender_cls, receivers: int = 2):
    ch = f"test-sender-{uuid.uuid4().hex[:8]}"
    rxs = [can.Bus(interface="virtual", channel=ch) for _ in range(receivers)]
    tx = sender_cls(channel=ch)
    try:
        sent = _frames()
        for m in sent:
            tx.send(m)
        got = [[b.recv(1.0) for _ in sent] for b in rxs]
        assert tx.recv(0.0) is None                      # no own messages unless asked
        return sent, got
    finally:
        for b in (*rxs, tx):
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


def test_a_lone_receiver_gets_the_sent_message_with_a_copys_fields():
    sent, (got,) = _received(SenderVirtualBus, receivers=1)
    _, (ref,) = _received(lambda channel: can.Bus(interface="virtual", channel=channel), receivers=1)
    fields = ("arbitration_id", "dlc", "is_extended_id", "is_remote_frame", "is_error_frame", "is_rx", "is_fd",
              "bitrate_switch", "error_state_indicator")
    for m, r, s in zip(got, ref, sent):
        assert m is s                                    # no copy: the sender never touches it again
        assert [getattr(m, f) for f in fields] == [getattr(r, f) for f in fields] and m.is_rx
        assert bytes(m.data) == bytes(r.data) and type(m.data) is type(r.data)
        assert m.channel.startswith("test-sender-") and m.timestamp > 0


def test_sender_bus_closed_raises():
    tx = SenderVirtualBus(channel=f"test-sender-{uuid.uuid4().hex[:8]}")
    tx.shutdown()
    with pytest.raises(can.CanOperationError):
        tx.send(_frames()[0])
