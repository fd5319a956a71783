"""RTDE v2 server (port 30004) of the controller stand-in.

Per connection: V/v/O/I/S/P/U/M as the controller answers them (reference ur-rtde.md §1, §9.2):
output recipes with each variable at its official type, `NOT_FOUND` for unknown names, input
recipes numbered 1, 2, 3, ... per connection (ur_rtde hard-codes those ids), `IN_USE` when another
live connection owns an input, inputs applied atomically per data package, and data packages
streamed from the controller tick at the requested rate. Streaming writes never block the tick:
they go out with MSG_DONTWAIT, and a client whose backlog passes `MAX_BACKLOG` bytes is dropped,
as the controller closes clients that stop reading.

A connection's output recipe is one immutable `OutputRecipe`, published to the tick thread by a
single assignment under `Controller.lock` (a new recipe never mixes with the old one in a
package). Recipe ids are one byte: the 256th output or input recipe on a connection is refused
(id 0, the failure answer), never a crash. A package type the protocol does not have ends the
connection.
"""
from __future__ import annotations

import array
import fcntl
import itertools
import socket
import struct
import termios
import threading
import time
from dataclasses import dataclass

import numpy as np

from sim.ursim.rtde_vars import INPUTS, OUTPUTS, TYPE_WIDTH, FrameReader, frame, record_format

MAX_BACKLOG = 1 << 20
#: Recipe ids are uint8 and 0 means "refused": at most 255 of each kind per connection.
MAX_RECIPES = 255
_ids = itertools.count(1)


@dataclass(frozen=True)
class OutputRecipe:
    """What one output recipe streams: names, flattened widths, the packing struct, its id, and
    the decimation (`every` controller periods)."""

    id: int
    names: tuple
    widths: tuple
    packer: struct.Struct
    every: int
    getters: tuple  # Controller.output_getter of each name


def _flatten(values, widths) -> list:
    flat = []
    for v, w in zip(values, widths):
        if w == 1:
            flat.append(v.item() if isinstance(v, np.generic) else v)
        elif np.ndim(v) == 0:  # a variable the stand-in does not model: zeros of the right width
            flat.extend([v] * w)
        else:
            flat.extend(np.asarray(v).tolist())
    return flat


class RTDEConnection:
    """One client connection: its recipes, its frames as the I/O loop reads them, and its share of
    the stream (written by the tick thread)."""

    def __init__(self, sock: socket.socket, ctrl):
        self.id = next(_ids)
        self.sock = sock
        self.ctrl = ctrl
        self.protocol = 1
        self.recipe: OutputRecipe | None = None  # published under ctrl.lock
        self.recipes_made = 0
        self.next_tick = 0
        self.started = False
        self.inputs: dict[int, tuple[list[str], struct.Struct, list[int]]] = {}
        self.next_input_id = 1
        self.backlog = bytearray()
        self.send_lock = threading.Lock()
        self.closed = False
        self.sent = 0
        self.reader = FrameReader()
        self.loop = None  # the I/O loop serving this connection (set on open)
        self._reply_due = 0.0
        self._handling = False  # the I/O loop is handling bytes it has read from this client

    # ---- sending -------------------------------------------------------------------------------
    def _send(self, data: bytes) -> None:
        with self.send_lock:
            if self.closed:
                return
            self.backlog += data
            self._flush()

    def _flush(self) -> None:
        while self.backlog:
            try:
                n = self.sock.send(self.backlog, socket.MSG_DONTWAIT)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                self.close()
                return
            del self.backlog[:n]
        if len(self.backlog) > MAX_BACKLOG:
            self.ctrl.log(f"rtde client {self.id}: not reading, receive buffer overflow: closing")
            self.close()

    def maybe_send(self, k: int, ctrl) -> None:
        """Called every tick: send a data package if this client is due one."""
        with ctrl.lock:
            rec = self.recipe
            due = self.started and not self.closed and rec is not None and k >= self.next_tick
            if due:
                self.next_tick = k + rec.every * ctrl.stream_decimate
                values = [g() for g in rec.getters]
        if not due:
            if self.backlog:
                with self.send_lock:
                    self._flush()
            return
        payload = struct.pack(">B", rec.id) + rec.packer.pack(*_flatten(values, rec.widths))
        self._send(frame(b"U", payload))
        self.sent += 1

    def close(self) -> None:
        """End the connection (from any thread): the socket is shut down at once, and the I/O loop,
        which then reads its end, closes it and releases its client slot."""
        if self.closed:
            return
        self.closed = True
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    # ---- receiving (the I/O loop's handler: io_loop.Handler) -----------------------------------
    def on_open(self, conn) -> None:
        self.loop = conn.loop
        with self.ctrl.lock:
            self.ctrl.rtde_conns.append(self)

    def on_data(self, conn, data: bytes) -> None:
        self._handling = True
        try:
            for kind, payload in self.reader.feed(data):
                self._handle(kind, payload)
        except Exception as exc:  # a malformed stream ends this connection only
            self.ctrl.log(f"rtde client {self.id}: {type(exc).__name__}: {exc}")
            self.close()
            conn.loop.close(conn)
        finally:
            self._handling = False

    def input_waiting(self) -> bool:
        """Has this client sent bytes the stand-in has not acted on yet (in the kernel's receive
        queue, a partial frame, or a frame being handled)? Then the client is not quiet: the
        stand-in's own network thread is behind, which a controller's never is."""
        if self.closed:
            return False
        if self._handling or self.reader.pending():
            return True
        try:
            waiting = array.array("i", [0])
            fcntl.ioctl(self.sock.fileno(), termios.FIONREAD, waiting)
            return waiting[0] > 0
        except (OSError, ValueError):
            return False

    def on_close(self, conn) -> None:
        self.close()
        with self.ctrl.lock:
            if self in self.ctrl.rtde_conns:
                self.ctrl.rtde_conns.remove(self)
            for name in [n for n, owner in self.ctrl.owners.items() if owner == self.id]:
                del self.ctrl.owners[name]

    def _reply(self, kind: bytes, payload: bytes) -> None:
        """Answer now, or as late as the `slow` fault says (replies stay in order)."""
        with self.ctrl.lock:
            delay = self.ctrl.reply_delay
        now = time.monotonic()
        if delay <= 0 and self._reply_due <= now:
            self._send(frame(kind, payload))
            return
        self._reply_due = max(now + delay, self._reply_due)
        data = frame(kind, payload)
        self.loop.call_at(self._reply_due, lambda: self._send(data))

    def _handle(self, kind: int, payload: bytes) -> None:
        ctrl = self.ctrl
        k = chr(kind)
        if k == "V":
            (self.protocol,) = struct.unpack(">H", payload[:2])
            self._reply(b"V", b"\x01" if self.protocol in (1, 2) else b"\x00")
        elif k == "v":
            self._reply(b"v", struct.pack(">IIII", *ctrl.cfg.version))
        elif k == "O":
            self._setup_outputs(payload)
        elif k == "I":
            self._setup_inputs(payload)
        elif k == "S":
            with ctrl.lock:
                ok = self.recipe is not None
                if ok:
                    self.started = True
                    self.next_tick = ctrl.tick_index + 1
            self._reply(b"S", b"\x01" if ok else b"\x00")
        elif k == "P":
            with ctrl.lock:
                self.started = False
            self._reply(b"P", b"\x01")
        elif k == "U":
            self._data(payload)
        elif k == "M":
            pass
        else:
            raise ValueError(f"unknown package type {kind}")

    def _setup_outputs(self, payload: bytes) -> None:
        ctrl = self.ctrl
        if self.protocol >= 2:
            if len(payload) < 8:
                raise ValueError("output setup without a frequency")
            (freq,) = struct.unpack(">d", payload[:8])
            text = payload[8:].decode("ascii", "replace")
        else:
            freq, text = 125.0, payload.decode("ascii", "replace")
        names = [n.strip() for n in text.split(",") if n.strip()]
        types = [OUTPUTS.get(n, "NOT_FOUND") for n in names]
        base = 1.0 / ctrl.period
        full = self.recipes_made >= MAX_RECIPES
        if full:
            ctrl.log(f"rtde client {self.id}: {MAX_RECIPES} output recipes already: refused")
        if "NOT_FOUND" in types or not names or not (0 < freq <= base + 1e-9) or full:
            self._reply(b"O", b"\x00" + ",".join(types).encode())
            return
        self.recipes_made += 1
        rec = OutputRecipe(id=self.recipes_made, names=tuple(names), widths=tuple(TYPE_WIDTH.get(t, 1) for t in types),
                           packer=record_format(types), every=max(1, int(round(base / freq))),
                           getters=tuple(ctrl.output_getter(n) for n in names))
        with ctrl.lock:
            self.recipe = rec  # one assignment: the tick streams the old recipe or the new one, whole
        self._reply(b"O", struct.pack(">B", rec.id) + ",".join(types).encode())

    def _setup_inputs(self, payload: bytes) -> None:
        ctrl = self.ctrl
        names = [n.strip() for n in payload.decode("ascii", "replace").split(",") if n.strip()]
        with ctrl.lock:
            types = []
            for n in names:
                if n not in INPUTS:
                    types.append("NOT_FOUND")
                elif ctrl.owners.get(n, self.id) != self.id and ctrl.owners[n] in {c.id for c in ctrl.rtde_conns}:
                    types.append("IN_USE")
                else:
                    types.append(INPUTS[n])
            if "NOT_FOUND" in types or "IN_USE" in types or not names or self.next_input_id > MAX_RECIPES:
                rid = 0
            else:
                rid = self.next_input_id
                self.next_input_id += 1
                for n in names:
                    ctrl.owners[n] = self.id
                self.inputs[rid] = (names, record_format(types), [TYPE_WIDTH.get(t, 1) for t in types])
        self._reply(b"I", struct.pack(">B", rid) + ",".join(types).encode())

    def _data(self, payload: bytes) -> None:
        if not payload:
            raise ValueError("data package without a recipe id")
        rid = payload[0]
        recipe = self.inputs.get(rid)
        if recipe is None:
            self.ctrl.log(f"rtde client {self.id}: data package for unknown input recipe {rid}: ignored")
            return
        names, st, widths = recipe
        if len(payload) - 1 != st.size:
            self.ctrl.log(f"rtde client {self.id}: input recipe {rid} expects {st.size} bytes, "
                          f"got {len(payload) - 1}: ignored")
            return
        flat = st.unpack(payload[1:])
        values, i = {}, 0
        for n, w in zip(names, widths):
            values[n] = flat[i] if w == 1 else np.array(flat[i:i + w])
            i += w
        self.ctrl.apply_inputs(values)


def serve_rtde(ctrl, loop, listener: socket.socket) -> None:
    """Serve RTDE clients from the I/O loop `loop` (within the client cap)."""
    def handler(sock: socket.socket) -> RTDEConnection:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return RTDEConnection(sock, ctrl)

    loop.listen(listener, "rtde", handler)
