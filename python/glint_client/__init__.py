"""glint's Python client: live zero-copy subscriptions to a running deployment over iceoryx2
(``Client``), ``run.mcap`` recordings (``Recording``), deployment discovery (``GlintRun``,
``prefix_from_report`` …) and glint's wire layouts as numpy dtypes / ctypes (``Layouts``)."""

from .digest import FrameDigest, MessageDigest
from .discovery import (
    DiscoveryError,
    GlintRun,
    live_nodes,
    prefix_from_log_line,
    prefix_from_report,
    prefixes_in_shm,
    wait_for_new_prefix,
)
from .layout import CONTRACT_VERSION, Layouts, LayoutError, TypeLayout, View, decode
from .live import Client, Frame, FrameSubscriber, FramesHeldError, LiveError, Message, \
    MessageSubscriber
from .recording import RecordedFrame, RecordedJson, RecordedMessage, RecordedRaw, Recording, \
    RecordingError

__all__ = [
    "CONTRACT_VERSION", "Client", "DiscoveryError", "Frame", "FrameDigest", "FrameSubscriber",
    "FramesHeldError", "GlintRun", "LayoutError", "Layouts", "LiveError", "Message",
    "MessageDigest", "MessageSubscriber", "RecordedFrame", "RecordedJson", "RecordedMessage", "RecordedRaw", "Recording",
    "RecordingError", "TypeLayout", "View", "decode", "live_nodes", "prefix_from_log_line",
    "prefix_from_report", "prefixes_in_shm", "wait_for_new_prefix",
]
