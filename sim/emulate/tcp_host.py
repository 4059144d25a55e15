"""Host an emulated device on a TCP port: reachable as ``socket://127.0.0.1:<port>`` from pyserial (and GeoComPy's
``open_socket``), also from another process or machine.  One client at a time, like a serial-to-Ethernet adapter.
"""
from __future__ import annotations

import select
import socket
import threading

from sim.emulate.device import ByteDevice
from sim.emulate.pty_host import FailureHook, run_guarded


class TcpHost:
    def __init__(self, device: ByteDevice, host: str = "127.0.0.1", port: int = 0, *,
                 on_failure: FailureHook | None = None):
        self.device = device
        self.on_failure = on_failure
        self.failure: BaseException | None = None
        self._srv = socket.create_server((host, port))
        self.host, self.port = self._srv.getsockname()[:2]
        self.url = f"socket://{self.host}:{self.port}"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"tcp-{device.label}", daemon=True)
        self._thread.start()

    def describe(self) -> str:
        return f"the TCP server of {self.device.label} on {self.url}"

    def _run(self) -> None:
        run_guarded(self, self._serve)

    def _serve(self) -> None:
        period = min(self.device.tick_period_s or 0.05, 0.05)
        while not self._stop.is_set():
            r, _, _ = select.select([self._srv], [], [], 0.1)
            if not r:
                continue
            try:
                conn, _ = self._srv.accept()
            except OSError:
                if self._stop.is_set():
                    return
                raise
            with conn:
                self.device.read_output()                 # a new client does not get the last one's leftovers
                while not self._stop.is_set():
                    r, _, _ = select.select([conn], [], [], period)
                    if r:
                        try:
                            data = conn.recv(65536)
                        except OSError:
                            break
                        if not data:
                            break
                        self.device.feed(data)
                    self.device.tick()
                    out = self.device.read_output()
                    if out:
                        try:
                            conn.sendall(out)
                        except OSError:
                            break

    def close(self) -> None:
        self._stop.set()
        try:
            self._srv.close()
        except OSError:
            pass
        self._thread.join(1.0)

    def __enter__(self) -> "TcpHost":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
