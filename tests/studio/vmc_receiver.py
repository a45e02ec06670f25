"""A VMC receiver for tests: a UDP socket on loopback whose every OSC bundle is decoded as it arrives."""
from __future__ import annotations

import socket
import threading
from contextlib import contextmanager

from pythonosc.osc_packet import OscPacket


@contextmanager
def vmc_receiver():
    """(port, bundles): each received packet as [(address, params), ...], appended in arrival order."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.2)
    bundles, stop = [], threading.Event()

    def run():
        while not stop.is_set():
            try:
                data, _ = sock.recvfrom(65536)
            except socket.timeout:
                continue
            bundles.append([(m.message.address, m.message.params) for m in OscPacket(data).messages])

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield sock.getsockname()[1], bundles
    finally:
        stop.set()
        thread.join()
        sock.close()
