"""The boundary's frame codec: what is encoded decodes as it was; anything else is a FrameError."""

import struct

from hypothesis import given, settings, strategies as st
import pytest
from sim_bridge.runner.boundary.wire.frames import (
    encode, Frame, FrameDecoder, FrameError, MAX_HEADER_BYTES, Message, PREFIX)

KINDS = ('advance', 'idle', 'sync')
topics = st.from_regex(r'(/[a-z_][a-z0-9_]{0,8}){1,3}', fullmatch=True)
types = st.sampled_from(['geometry_msgs/msg/Twist', 'sensor_msgs/msg/LaserScan'])
messages = st.lists(st.builds(Message, topics, types, st.binary(max_size=64)), max_size=5)


@given(messages, st.integers(0, 2 ** 62), st.lists(st.integers(1, 40), max_size=6))
def test_a_frame_decodes_to_what_was_encoded_in_any_chunks(listed, wake_ns, cuts):
    data = encode('idle', listed, wake_ns=wake_ns, node='wall_follow') * 2
    decoder, frames, position = FrameDecoder(KINDS), [], 0
    for cut in cuts + [len(data)]:
        frames += decoder.feed(data[position:position + cut])
        position += cut
    frames += decoder.feed(data[position:])
    assert frames == [Frame('idle', {'wake_ns': wake_ns, 'node': 'wall_follow'}, listed)] * 2
    assert not decoder.partial


@settings(max_examples=300)
@given(st.binary(max_size=300))
def test_garbage_is_a_frame_error_or_an_incomplete_frame_never_anything_else(data):
    decoder = FrameDecoder(KINDS)
    try:
        frames = decoder.feed(data)
    except FrameError:
        return
    assert all(frame.kind in KINDS for frame in frames)


@settings(max_examples=300)
@given(st.recursive(st.none() | st.booleans() | st.integers() | st.text(max_size=8),
                    lambda inner: st.lists(inner, max_size=3)
                    | st.dictionaries(st.text(max_size=5), inner, max_size=3), max_leaves=12),
       st.binary(max_size=40))
def test_any_json_header_is_a_frame_or_a_frame_error(header, payload):
    import json
    body = json.dumps(header).encode()
    data = PREFIX.pack(len(body), len(payload)) + body + payload
    try:
        frames = FrameDecoder(KINDS).feed(data)
    except FrameError:
        return
    assert [frame.kind for frame in frames] == [header['kind']]


@pytest.mark.parametrize('header, reason', [
    (b'{"kind": "idle", "messages": [["/cmd_vel", "os.system", 0]]}', 'type'),
    (b'{"kind": "idle", "messages": [["cmd vel", "geometry_msgs/msg/Twist", 0]]}', 'topic'),
    (b'{"kind": "idle", "messages": [["/a", "geometry_msgs/msg/Twist", 9]]}', 'size'),
    (b'{"kind": "pickle"}', 'kind'),
    (b'\x80\x04\x95', 'JSON'),
    (b'[' * 100_000 + b']' * 100_000, 'JSON'),
    (b'{"kind": "idle", "wake_ns": ' + b'9' * 10_000 + b'}', 'JSON'),
])
def test_a_malformed_frame_says_why_in_one_line(header, reason):
    with pytest.raises(FrameError, match=reason) as error:
        FrameDecoder(KINDS).feed(PREFIX.pack(len(header), 0) + header)
    assert '\n' not in str(error.value)


def test_a_frame_over_the_size_limit_is_refused_before_it_is_read():
    with pytest.raises(FrameError, match='over the limit'):
        FrameDecoder(KINDS).feed(struct.pack('>II', MAX_HEADER_BYTES + 1, 0))


def test_fields_are_read_only_as_the_type_asked_for():
    frame = FrameDecoder(KINDS).feed(encode('idle', wake_ns='soon', node=['x']))[0]
    with pytest.raises(FrameError, match='wake_ns must be an integer'):
        frame.integer('wake_ns')
    with pytest.raises(FrameError, match='node must be a string'):
        frame.text('node')
    assert frame.integer('missing', optional=True) is None
