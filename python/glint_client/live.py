"""Live subscriptions to a running glint deployment over iceoryx2 shared memory.

``Client(prefix)`` is one iceoryx2 node under the deployment's prefix. It opens (never
creates) the deployment's services, with the contract attribute ``glint.contract`` required,
and adds one subscriber per topic it subscribes to. It is an *observer*: the orchestrator lists
it in ``report.json`` (``membership.strangers``) and never waits for it, so in sim-clock mode a
client slower than the chain misses frames (counted by ``FrameSubscriber.missed``). Keep the
receive loop light (no per-message garbage: decode and convert after), and wait on every topic
at once (``Client.wait`` / ``Client.stream``): each queue holds 16 messages.

Frames are zero-copy: ``Frame.pixels`` is a read-only ``uint16`` array of shape
``(height_px, width_px)`` over the shared-memory sample itself; ``Frame.header`` is a copy.

**Lifetime.** The pixel array owns the sample's loan: it (and every view sliced from it) holds
the iceoryx2 sample through its ``base`` chain, so the memory stays valid as long as any array
over it lives, and is given back to the publisher when the last one is gone (CPython frees it
at once). ``Frame.release()`` / leaving ``with frame:`` drops the frame's own hold; the
streams release each frame when the next item is asked for. A subscriber may hold at most
``subscriber_max_borrowed_samples`` frames at once (2 in glint): keeping more arrays alive makes
``receive`` raise ``FramesHeldError`` — copy what you keep (``frame.copy()``). Arrays still
alive at ``close()`` keep the node's memory mapped until they go (a ``ResourceWarning`` says
so); at interpreter exit an ``atexit`` hook gives every loan back and closes every client, so
the node never outlives the process.

Messages (``detections``, ``tracks`` …) are small: each is copied out of shared memory and its
sample given back at once.
"""

from __future__ import annotations

import atexit
import ctypes
import time
import warnings
import weakref
from dataclasses import dataclass
from typing import Any, Iterator

import numpy as np

import iceoryx2 as iox

from .discovery import is_prefix
from .layout import CONTRACT_VERSION, Layouts, View

#: The attribute every glint service carries; opening requires it.
CONTRACT_KEY = "glint.contract"
DEFAULT_NODE_NAME = "glint-py"


class LiveError(RuntimeError):
    """A deployment's service could not be opened or read."""


class FramesHeldError(LiveError):
    """``receive`` with as many frames held as the service allows (their arrays still live)."""


_log_level_set = False


def _quiet_iceoryx() -> None:
    global _log_level_set
    if not _log_level_set:
        iox.set_log_level_from_env_or(iox.LogLevel.Error)
        _log_level_set = True


def _wait(listener: Any, timeout: float) -> None:
    if listener is None:
        time.sleep(min(timeout, 0.0005))
    else:
        listener.timed_wait(iox.Duration.from_secs_f64(max(timeout, 0.0)))


@dataclass(frozen=True)
class Qos:
    """What the service was created with (the Rust side's numbers)."""

    max_publishers: int
    max_subscribers: int
    max_nodes: int
    history_size: int
    subscriber_max_buffer_size: int
    subscriber_max_borrowed_samples: int
    safe_overflow: bool

    @staticmethod
    def of(service: Any) -> Qos:
        c = service.static_config
        return Qos(c.max_publishers, c.max_subscribers, c.max_nodes, c.history_size,
                   c.subscriber_max_buffer_size, c.subscriber_max_borrowed_samples,
                   c.has_safe_overflow)


class _Topic:
    """A subscriber on one of the deployment's publish-subscribe services, and the listener
    on the event service of the same name that its producer notifies after each send."""

    def __init__(self, client: Client, topic: str, payload: Any, header: Any | None,
                 buffer_size: int | None, wake: bool):
        self.topic = topic
        self.client = client
        name = iox.ServiceName.new(f"glint/{topic}")
        builder = client.node.service_builder(name).publish_subscribe(payload)
        if header is not None:
            builder = builder.user_header(header)
        try:
            self._service = builder.open_with_attributes(client.verifier)
        except iox.PublishSubscribeOpenError as e:
            raise LiveError(f"opening glint/{topic} under {client.prefix}: {e!r} (does the "
                            f"deployment run, with this topic and contract "
                            f"{CONTRACT_VERSION}?)") from e
        self.qos = Qos.of(self._service)
        sb = self._service.subscriber_builder()
        if buffer_size is not None:
            sb = sb.buffer_size(buffer_size)
        self._sub = sb.create()
        self._events: Any = None
        self._listener: Any = None
        if wake:
            try:
                self._events = (client.node.service_builder(name).event()
                                .open_with_attributes(client.verifier))
                self._listener = self._events.listener_builder().create()
            except (iox.EventOpenError, iox.ListenerCreateError):
                self._listener = None  # polls instead
        #: Whether a publisher was ever seen: "no publisher" then means the producer ended.
        self._seen_publisher = False
        client._topics.append(self)  # held by the client until closed: stream() reads it

    def publishers(self) -> int:
        n = int(self._service.dynamic_config.number_of_publishers)
        self._seen_publisher |= n > 0
        return n

    def has_samples(self) -> bool:
        return self._sub is not None and bool(self._sub.has_samples())

    def producer_gone(self) -> bool:
        """The producer was seen and has no publisher any more (it ended or died)."""
        return self.publishers() == 0 and self._seen_publisher

    def _receive_sample(self) -> Any | None:
        if self._sub is None:
            raise LiveError(f"glint/{self.topic}: subscriber closed")
        try:
            s = self._sub.receive()
            if s is not None:
                self._seen_publisher = True  # a sample: there was a producer
            return s
        except iox.ReceiveError as e:
            if "ExceedsMaxBorrows" in repr(e):
                raise FramesHeldError(
                    f"glint/{self.topic}: {self.qos.subscriber_max_borrowed_samples} samples "
                    "are still held (their arrays are alive); release or copy them") from e
            raise LiveError(f"glint/{self.topic}: {e!r}") from e

    def _wait_sample(self, timeout: float) -> Any | None:
        end = time.monotonic() + timeout
        while True:
            s = self._receive_sample()
            if s is not None:
                return s
            left = end - time.monotonic()
            if left <= 0:
                return None
            _wait(self._listener, min(left, 0.05))

    def close(self) -> None:
        if self._listener is not None:
            self.client._drop_waitset()  # it may hold the listener
            self._listener.delete()
            self._listener = None
        if self._sub is not None:
            self._sub.delete()
            self._sub = None
        self._events = None
        self._service = None
        if self in self.client._topics:
            self.client._topics.remove(self)


class Frame:
    """One frame: its header (a copy) and its pixels (a zero-copy read-only view)."""

    __slots__ = ("header", "_pixels", "__weakref__")

    def __init__(self, header: View, pixels: np.ndarray):
        self.header = header
        self._pixels: np.ndarray | None = pixels

    @property
    def pixels(self) -> np.ndarray:
        """``uint16[height_px, width_px]``, read-only, over the shared-memory sample."""
        if self._pixels is None:
            raise LiveError("frame released")
        return self._pixels

    @property
    def seq(self) -> int:
        return int(self.header.meta.seq)

    @property
    def frame_index(self) -> int:
        return int(self.header.frame_index)

    def copy(self) -> np.ndarray:
        """The pixels in ordinary (writeable) memory."""
        return self.pixels.copy()

    def checksum_ok(self) -> bool:
        """Whether xxh3-64 of the pixel bytes equals the header's ``pixels_xxh3``."""
        import xxhash

        return xxhash.xxh3_64_intdigest(self.pixels.data) == int(self.header.pixels_xxh3)

    def release(self) -> None:
        """Drops this frame's hold on the sample (given back once no array over it lives)."""
        self._pixels = None

    def __enter__(self) -> Frame:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __repr__(self) -> str:
        h = self.header
        return (f"Frame(seq={h.meta.seq}, index={h.frame_index}, {h.width_px}x{h.height_px}, "
                f"{'released' if self._pixels is None else 'held'})")


class _Loan:
    """A frame sample, held by the buffer under its pixel arrays (so by the arrays)."""

    __slots__ = ("sample", "__weakref__")

    def __init__(self, sample: Any):
        self.sample = sample


def pixel_view(sample: Any, header: View, loans: weakref.WeakSet[_Loan] | None = None
               ) -> np.ndarray:
    """The pixels of a frame sample as a read-only ``uint16`` array that keeps the sample.

    The binding's ``Slice`` length is not used as an element count: for a payload wider than a
    byte iceoryx2 0.10.0 reports its bytes (iceoryx2 issue 1533). The shape comes from the
    header, and is checked against the reported length, which may be bytes or elements.
    """
    w, h = int(header.width_px), int(header.height_px)
    reported = int(getattr(sample, "__slice_len"))
    if reported not in (w * h * 2, w * h):
        raise LiveError(f"frame payload of {reported} (bytes or pixels) for a {w}x{h} header")
    buf = (ctypes.c_uint8 * (w * h * 2)).from_address(int(sample.payload_ptr))
    loan = _Loan(sample)
    buf._glint_loan = loan  # type: ignore[attr-defined]  # the array's base keeps the loan
    if loans is not None:
        loans.add(loan)
    arr = np.frombuffer(memoryview(buf).toreadonly(), dtype="<u2").reshape(h, w)
    assert not arr.flags.writeable
    return arr


class FrameSubscriber(_Topic):
    """Frames of a frame topic (``frame``, ``earth_frame``): ``[u16]`` pixels with a
    ``glint.v8.FrameHeader`` user header."""

    def __init__(self, client: Client, topic: str = "frame", *, buffer_size: int | None = None,
                 wake: bool = True):
        self.header_type = client.layouts.topic_type(topic) if topic in client.layouts.topics \
            else client.layouts.get("FrameHeader")
        self._header_dtype = client.layouts.dtype(self.header_type.name)
        super().__init__(client, topic, iox.Slice[ctypes.c_uint16],
                         client.layouts.ctype(self.header_type.name), buffer_size, wake)
        self._current: Frame | None = None
        #: The samples whose pixel arrays are still alive somewhere.
        self._loans: weakref.WeakSet[_Loan] = weakref.WeakSet()
        self.received = 0
        #: Frames skipped between the ones received (seq gaps): the client was too slow.
        self.missed = 0
        self._next_seq: int | None = None

    def _frame(self, sample: Any) -> Frame:
        raw = ctypes.string_at(int(sample.user_header_ptr), self._header_dtype.itemsize)
        header = View(np.frombuffer(raw, dtype=self._header_dtype, count=1)[0])
        frame = Frame(header, pixel_view(sample, header, self._loans))
        seq = int(header.meta.seq)
        if self._next_seq is not None and seq > self._next_seq:
            self.missed += seq - self._next_seq
        self._next_seq = max(seq + 1, self._next_seq or 0)
        self.received += 1
        return frame

    def receive(self) -> Frame | None:
        """The next queued frame, or None (never blocks)."""
        s = self._receive_sample()
        return None if s is None else self._frame(s)

    def wait(self, timeout: float) -> Frame | None:
        """The next frame, waiting up to ``timeout`` seconds (woken by the producer's event)."""
        s = self._wait_sample(timeout)
        return None if s is None else self._frame(s)

    def stream(self, idle_timeout: float = 5.0) -> Iterator[Frame]:
        """Frames as they come, each released when the next is asked for. Ends when the
        producer has gone and nothing is queued, or after ``idle_timeout`` s without a frame."""
        last = time.monotonic()
        try:
            while True:
                if self._current is not None:
                    self._current.release()
                    self._current = None
                f = self.wait(0.05)
                if f is not None:
                    last = time.monotonic()
                    self._current = f
                    yield f
                elif self.producer_gone() and not self.has_samples():
                    return
                elif time.monotonic() - last > idle_timeout:
                    return
        finally:
            if self._current is not None:
                self._current.release()
                self._current = None

    __iter__ = stream

    def held(self) -> int:
        """Samples still held by live pixel arrays."""
        return len(self._loans)

    def close(self, *, force: bool = False) -> None:
        """Closes the subscriber. Samples still held by live pixel arrays keep the node's
        shared memory until those arrays are gone (a ``ResourceWarning`` says so); ``force``
        gives them back now, and those arrays must not be read again (the interpreter's exit
        does this)."""
        if self._current is not None:
            self._current.release()
            self._current = None
        loans = list(self._loans)
        if loans and force:
            for loan in loans:
                loan.sample.delete()
        elif loans:
            warnings.warn(f"glint/{self.topic}: {len(loans)} frame(s) still alive keep the "
                          "deployment's shared memory mapped until they are gone",
                          ResourceWarning, stacklevel=3)
        super().close()


@dataclass(frozen=True)
class Message:
    """One message, copied out of shared memory: ``value`` decoded, ``raw`` its bytes."""

    topic: str
    value: View
    raw: bytes

    def __getattr__(self, name: str) -> Any:
        return getattr(self.value, name)


class MessageSubscriber(_Topic):
    """A message topic (``detections``, ``tracks`` …): one ``#[repr(C)]`` struct per sample,
    its iceoryx2 type name the contract name (``glint.v8.Detections``)."""

    def __init__(self, client: Client, topic: str, *, type_name: str | None = None,
                 buffer_size: int | None = None, wake: bool = True):
        layout = client.layouts.get(type_name) if type_name else client.layouts.topic_type(topic)
        self.type = layout
        self._dtype = client.layouts.dtype(layout.name)
        super().__init__(client, topic, client.layouts.ctype(layout.name), None, buffer_size,
                         wake)
        self.received = 0

    def _message(self, sample: Any) -> Message:
        raw = ctypes.string_at(int(sample.payload_ptr), self._dtype.itemsize)
        sample.delete()  # copied: give the sample back at once
        self.received += 1
        return Message(self.topic, View(np.frombuffer(raw, dtype=self._dtype, count=1)[0]), raw)

    def receive(self) -> Message | None:
        s = self._receive_sample()
        return None if s is None else self._message(s)

    def wait(self, timeout: float) -> Message | None:
        s = self._wait_sample(timeout)
        return None if s is None else self._message(s)

    def drain(self) -> list[Message]:
        """Everything queued now."""
        out = []
        while (m := self.receive()) is not None:
            out.append(m)
        return out

    def stream(self, idle_timeout: float = 5.0) -> Iterator[Message]:
        """Messages as they come; ends as ``FrameSubscriber.stream`` does."""
        last = time.monotonic()
        while True:
            m = self.wait(0.05)
            if m is not None:
                last = time.monotonic()
                yield m
            elif self.producer_gone() and not self.has_samples():
                return
            elif time.monotonic() - last > idle_timeout:
                return

    __iter__ = stream


_open_clients: weakref.WeakSet[Client] = weakref.WeakSet()


class Client:
    """One iceoryx2 node under a deployment's prefix; subscribes to its topics.

    Close it (``close()`` or ``with``) when done: its node then leaves the deployment at once.
    Clients still open at interpreter exit are closed by an ``atexit`` hook.
    """

    def __init__(self, prefix: str, *, node_name: str = DEFAULT_NODE_NAME,
                 layouts: Layouts | None = None, contract_version: int = CONTRACT_VERSION):
        if not is_prefix(prefix):
            raise ValueError(f"{prefix!r} is not a glint deployment prefix (glint_<hex>_)")
        _quiet_iceoryx()
        self.prefix = prefix
        self.layouts = layouts or Layouts.bundled()
        cfg = iox.config.default()
        cfg.global_cfg.prefix = iox.FileName.new(prefix)
        # Named as no glint service is: a node named like one would be taken for an impostor.
        self.node: Any = (iox.NodeBuilder.new().name(iox.NodeName.new(node_name)).config(cfg)
                          .create(iox.ServiceType.Ipc))
        self.verifier = iox.AttributeVerifier.new().require(
            iox.AttributeKey.new(CONTRACT_KEY), iox.AttributeValue.new(str(contract_version)))
        self._topics: list[_Topic] = []
        self._waitset: Any = None
        self._guards: list[tuple[Any, _Topic]] = []
        _open_clients.add(self)

    def frames(self, topic: str = "frame", *, buffer_size: int | None = None,
               wake: bool = True) -> FrameSubscriber:
        """Subscribes to a frame topic. ``buffer_size``: frames queued for this subscriber
        (default and maximum: the service's, which is also its history, so a subscriber that
        joins early gets the frames sent before it joined)."""
        return FrameSubscriber(self, topic, buffer_size=buffer_size, wake=wake)

    def messages(self, topic: str, *, type_name: str | None = None,
                 buffer_size: int | None = None, wake: bool = True) -> MessageSubscriber:
        """Subscribes to a message topic; its type from the layouts' topic table unless
        ``type_name`` (a contract or Rust name) says otherwise."""
        return MessageSubscriber(self, topic, type_name=type_name, buffer_size=buffer_size,
                                 wake=wake)

    # -- waiting on every topic at once ----------------------------------------------------
    def _waitable(self) -> list[_Topic]:
        return [t for t in self._topics if t._listener is not None]

    def wait(self, timeout: float) -> set[str]:
        """Blocks until a producer of any subscribed topic notified (or ``timeout`` s passed);
        the topics it came from. One WaitSet over every subscriber's event listener: waiting
        on one topic while another fills would overflow the other's queue."""
        topics = self._waitable()
        if not topics:
            time.sleep(min(timeout, 0.0005))
            return set()
        if self._waitset is None or {id(t) for _, t in self._guards} != {id(t) for t in topics}:
            self._drop_waitset()
            self._waitset = iox.WaitSetBuilder.new().create(iox.ServiceType.Ipc)
            self._guards = [(self._waitset.attach_notification(t._listener), t) for t in topics]
        ids, _ = self._waitset.wait_and_process_with_timeout(
            iox.Duration.from_secs_f64(max(timeout, 0.0)))
        woken = set()
        for guard, t in self._guards:
            if any(i.has_event_from(guard) for i in ids):
                t._listener.try_wait()  # take the events, or the WaitSet fires again at once
                woken.add(t.topic)
        return woken

    def _drop_waitset(self) -> None:
        for guard, _ in self._guards:
            guard.delete()
        self._guards = []
        if self._waitset is not None:
            self._waitset.delete()
            self._waitset = None

    def stream(self, idle_timeout: float = 5.0) -> Iterator[Frame | Message]:
        """Everything every subscriber receives, in the order taken (each topic drained in
        turn), each frame released when the next item is asked for. Ends when every producer
        has gone and nothing is queued, or after ``idle_timeout`` s with nothing."""
        last = time.monotonic()
        current: Frame | None = None
        try:
            while True:
                got = False
                for t in list(self._topics):
                    while True:
                        if current is not None:
                            current.release()
                            current = None
                        item = t.receive()  # type: ignore[attr-defined]
                        if item is None:
                            break
                        got = True
                        if isinstance(item, Frame):
                            current = item
                        yield item
                if got:
                    last = time.monotonic()
                    continue
                topics = list(self._topics)
                if topics and all(t.producer_gone() and not t.has_samples() for t in topics):
                    return
                if time.monotonic() - last > idle_timeout:
                    return
                self.wait(0.05)
        finally:
            if current is not None:
                current.release()

    def close(self, *, force: bool = False) -> None:
        """Closes every subscriber and the node. Frame arrays still alive keep their samples
        (and the node's memory under them) until they are gone, unless ``force``
        (``FrameSubscriber.close``)."""
        self._drop_waitset()
        for t in list(self._topics):
            if isinstance(t, FrameSubscriber):
                t.close(force=force)
            else:
                t.close()
        self._topics = []
        self.node = None
        _open_clients.discard(self)

    @property
    def closed(self) -> bool:
        return self.node is None

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@atexit.register
def _close_all() -> None:
    # At exit nothing reads a frame any more; objects the interpreter does not free would
    # otherwise keep the node, and the deployment's files with it, past the process.
    for c in list(_open_clients):
        c.close(force=True)
