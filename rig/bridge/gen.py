"""Generates the bridge's C side of the link from the one message table (rig/bridge/messages.py):
``build/gen/bridge_messages.h`` with the ids, a struct per message, encoders and decoders of the bodies
(little-endian, floats as binary32, whatever the MCU's own layout), a union of all messages, and a
printer of decoded messages (JSON lines) that the tests compare with the host's decoder.

``python -m rig.bridge.gen [OUT]`` writes it; the bridge's builds (build/vbridge, the firmware, the
core's tests) call it first. It depends on nothing but the table (and the fault vocabulary it indexes).
"""

from __future__ import annotations

import sys
from pathlib import Path

from rig.bridge.messages import HOST_SILENT_US, MAX_FRAME, MESSAGES, PROTOCOL_VERSION, TYPES, Field, Message
from rig.emulators.faults import BUS_KINDS, BUS_TARGETS, KINDS, TARGETS
from rig.emulators.pwm_capture import CanCodec
from rig.plant.artifacts import BUILD
from rig.plant.native_build import write_text_if_changed

OUT = BUILD / "gen" / "bridge_messages.h"
SIZES = {"u8": 1, "u16": 2, "u32": 4, "u64": 8, "i16": 2, "i32": 4, "f32": 4}
PRINTF = {"u8": "%u", "u16": "%u", "u32": "%lu", "u64": "%llu", "i16": "%d", "i32": "%ld", "f32": "%.9g"}
CAST = {"u8": "unsigned", "u16": "unsigned", "u32": "unsigned long", "u64": "unsigned long long",
        "i16": "int", "i32": "long", "f32": "double"}


def _lower(m: Message) -> str:
    return m.name.lower()


def _struct(m: Message) -> list[str]:
    body = [f"    {TYPES[f.type][1]} {f.name}{f'[{f.count}]' if f.count > 1 else ''};" for f in m.fields]
    return [f"/* {m.doc} ({m.direction}) */", f"struct bridge_{_lower(m)} {{",
            *(body or ["    uint8_t unused_; /* no fields */"]), "};"]


def _put(f: Field, src: str) -> str:
    return f"bridge_put_{f.type}(p, {src}); p += {SIZES[f.type]};"


def _get(f: Field, dst: str) -> str:
    return f"{dst} = bridge_get_{f.type}(p); p += {SIZES[f.type]};"


def _codec(m: Message) -> list[str]:
    size = sum(SIZES[f.type] * f.count for f in m.fields)
    enc, dec = [], []
    for f in m.fields:
        if f.count > 1:
            enc.append(f"    for (int i = 0; i < {f.count}; i++) {{ {_put(f, f'm->{f.name}[i]')} }}")
            dec.append(f"    for (int i = 0; i < {f.count}; i++) {{ {_get(f, f'm->{f.name}[i]')} }}")
        else:
            enc.append(f"    {_put(f, f'm->{f.name}')}")
            dec.append(f"    {_get(f, f'm->{f.name}')}")
    n = _lower(m)
    return [
        f"#define BRIDGE_{m.name}_SIZE {size}",
        f"static inline size_t bridge_encode_{n}(uint8_t *p, const struct bridge_{n} *m)",
        "{", "    (void)p;", "    (void)m;", *enc, f"    return {size};", "}",
        f"static inline void bridge_decode_{n}(const uint8_t *p, struct bridge_{n} *m)",
        "{", "    (void)p;", "    (void)m;", *dec, "}",
    ]


def _printer(m: Message) -> list[str]:
    parts = []
    for f in m.fields:
        if f.count > 1:
            parts.append(f'    fprintf(out, ", \\"{f.name}\\": [");')
            parts.append(f"    for (int i = 0; i < {f.count}; i++)")
            parts.append(f'        fprintf(out, "%s{PRINTF[f.type]}", i ? ", " : "", ({CAST[f.type]})m->{f.name}[i]);')
            parts.append('    fprintf(out, "]");')
        else:
            parts.append(f'    fprintf(out, ", \\"{f.name}\\": {PRINTF[f.type]}", ({CAST[f.type]})m->{f.name});')
    return [f"    case BRIDGE_{m.name}: {{", f"        const struct bridge_{_lower(m)} *m = &msg->u.{_lower(m)};",
            "        (void)m;", *["    " + p for p in parts], "        break;", "    }"]


def _can_capture() -> list[str]:
    """The PWM capture frames of emulators/pwm_capture.dbc (the bridge sends them on CAN when its port
    has one): per frame its id and where each signal's bits are (Intel order). The generator checks
    what the C side takes for granted: widths in 0.1 µs, the CRC after the bytes it covers."""
    rows, first = [], []
    for k, msg in enumerate(CanCodec().messages):
        sig = {s.name: s for s in msg.signals}
        a, b = sig[f"PWM{2 * k + 1}"], sig[f"PWM{2 * k + 2}"]
        seq, crc = sig["SEQ"], sig["CRC16"]
        if not all(s.byte_order == "little_endian" for s in (a, b, seq, crc)):
            raise ValueError(f"{msg.name}: the bridge packs Intel (little-endian) signals only")
        if a.scale != 0.1 or b.scale != 0.1 or a.length != 16 or b.length != 16 or crc.length != 16:
            raise ValueError(f"{msg.name}: PWM signals of 16 bits in 0.1 us and a 16-bit CRC expected")
        if crc.start % 8 or msg.length != 8:
            raise ValueError(f"{msg.name}: the CRC must start on a byte of an 8-byte frame")
        rows.append(f"    {{ 0x{msg.frame_id:03x}, {{ {a.start}, {b.start} }}, {seq.start}, {seq.length}, "
                    f"{crc.start} }}, /* {msg.name} */")
        first.append(k)
    return [
        "/* PWM capture frames on CAN (emulators/pwm_capture.dbc): frame k carries motors 2k+1 and 2k+2 as",
        "   16-bit widths in 0.1 us, a sequence byte shared by the frames of one report, and a CRC-16/CCITT-FALSE",
        "   over the 11-bit identifier (2 bytes, big endian) and the data bytes before the CRC. */",
        f"#define BRIDGE_CAN_CAPTURE_FRAMES {len(rows)}",
        "struct bridge_can_capture {", "    uint16_t id;", "    uint8_t pwm_start[2];", "    uint8_t seq_start, seq_len;",
        "    uint8_t crc_start;", "};",
        "static const struct bridge_can_capture BRIDGE_CAN_CAPTURE[BRIDGE_CAN_CAPTURE_FRAMES] = {", *rows, "};",
        "/* ``len`` bits of ``v`` at bit ``start`` of ``data``, Intel order (the DBC's @1) */",
        "static inline void bridge_put_bits(uint8_t *data, unsigned start, unsigned len, uint32_t v)",
        "{", "    for (unsigned i = 0; i < len; i++) {", "        unsigned bit = start + i;",
        "        if (v >> i & 1u)", "            data[bit / 8] |= (uint8_t)(1u << (bit % 8));", "        else",
        "            data[bit / 8] &= (uint8_t)~(1u << (bit % 8));", "    }", "}", "",
    ]


def header() -> str:
    lines = [
        "/* Generated by rig/bridge/gen.py from rig/bridge/messages.py: do not edit. */",
        "#ifndef BRIDGE_MESSAGES_H", "#define BRIDGE_MESSAGES_H", "",
        "#include <stddef.h>", "#include <stdint.h>", "#include <string.h>", "",
        f"#define BRIDGE_PROTOCOL_VERSION {PROTOCOL_VERSION}",
        f"#define BRIDGE_HOST_SILENT_US {HOST_SILENT_US}",
        f"#define BRIDGE_MAX_FRAME {MAX_FRAME}", "",
        "/* FAULT's target and kind: indices in emulators.faults.TARGETS and KINDS (the bus ones) */",
        *[f"#define BRIDGE_FAULT_TARGET_{t.upper()} {TARGETS.index(t)}" for t in BUS_TARGETS],
        *[f"#define BRIDGE_FAULT_KIND_{k.upper()} {KINDS.index(k)}" for k in BUS_KINDS], "",
        "/* the link carries binary32 floats (C99 has no _Static_assert: a negative array size fails) */",
        "typedef char bridge_float_is_binary32[sizeof(float) == 4 ? 1 : -1];", "",
        "enum bridge_msg_id {",
        *[f"    BRIDGE_{m.name} = 0x{m.id:02x}," for m in MESSAGES], "};", "",
        "/* little-endian fields, whatever the host's or the MCU's own order */",
        "static inline void bridge_put_u8(uint8_t *p, uint8_t v) { p[0] = v; }",
        "static inline void bridge_put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }",
        "static inline void bridge_put_u32(uint8_t *p, uint32_t v)",
        "{", "    for (int i = 0; i < 4; i++)", "        p[i] = (uint8_t)(v >> (8 * i));", "}",
        "static inline void bridge_put_u64(uint8_t *p, uint64_t v)",
        "{", "    for (int i = 0; i < 8; i++)", "        p[i] = (uint8_t)(v >> (8 * i));", "}",
        "static inline void bridge_put_i16(uint8_t *p, int16_t v) { bridge_put_u16(p, (uint16_t)v); }",
        "static inline void bridge_put_i32(uint8_t *p, int32_t v) { bridge_put_u32(p, (uint32_t)v); }",
        "static inline void bridge_put_f32(uint8_t *p, float v)",
        "{", "    uint32_t u;", "    memcpy(&u, &v, 4);", "    bridge_put_u32(p, u);", "}",
        "static inline uint8_t bridge_get_u8(const uint8_t *p) { return p[0]; }",
        "static inline uint16_t bridge_get_u16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }",
        "static inline uint32_t bridge_get_u32(const uint8_t *p)",
        "{", "    uint32_t v = 0;", "    for (int i = 3; i >= 0; i--)", "        v = v << 8 | p[i];", "    return v;", "}",
        "static inline uint64_t bridge_get_u64(const uint8_t *p)",
        "{", "    uint64_t v = 0;", "    for (int i = 7; i >= 0; i--)", "        v = v << 8 | p[i];", "    return v;", "}",
        "static inline int16_t bridge_get_i16(const uint8_t *p) { return (int16_t)bridge_get_u16(p); }",
        "static inline int32_t bridge_get_i32(const uint8_t *p) { return (int32_t)bridge_get_u32(p); }",
        "static inline float bridge_get_f32(const uint8_t *p)",
        "{", "    uint32_t u = bridge_get_u32(p);", "    float v;", "    memcpy(&v, &u, 4);", "    return v;", "}", "",
    ]
    lines += _can_capture()
    for m in MESSAGES:
        lines += [*_struct(m), *_codec(m), ""]
    lines += ["/* any message: its id, its sequence byte and its fields */", "struct bridge_msg {",
              "    uint8_t id;", "    uint8_t seq;", "    union {",
              *[f"        struct bridge_{_lower(m)} {_lower(m)};" for m in MESSAGES], "    } u;", "};", ""]
    lines += ["/* The body of message ``id`` into ``msg``: 0, or -1 for an unknown id, -2 for a wrong body size, -3",
              "   for a message that goes the other way (``up``: 1 when decoding what a bridge sent). */",
              "static inline int bridge_decode_body(uint8_t id, const uint8_t *body, size_t n, int up,"
              " struct bridge_msg *msg)",
              "{", "    msg->id = id;", "    switch (id) {"]
    for m in MESSAGES:
        lines += [f"    case BRIDGE_{m.name}:",
                  f"        if (n != BRIDGE_{m.name}_SIZE)", "            return -2;",
                  f"        if (up != {int(m.direction == 'up')})", "            return -3;",
                  f"        bridge_decode_{_lower(m)}(body, &msg->u.{_lower(m)});", "        return 0;"]
    lines += ["    default:", "        return -1;", "    }", "}", "",
              "/* The body of ``msg`` into ``body`` (BRIDGE_MAX_FRAME bytes are enough); its size, 0 for an unknown id. */",
              "static inline size_t bridge_encode_body(const struct bridge_msg *msg, uint8_t *body)", "{",
              "    switch (msg->id) {"]
    for m in MESSAGES:
        lines += [f"    case BRIDGE_{m.name}:", f"        return bridge_encode_{_lower(m)}(body, &msg->u.{_lower(m)});"]
    lines += ["    default:", "        return 0;", "    }", "}", "",
              "/* The name of message ``id`` (NULL if unknown). */",
              "static inline const char *bridge_msg_name(uint8_t id)", "{", "    switch (id) {",
              *[f"    case BRIDGE_{m.name}:\n        return \"{m.name}\";" for m in MESSAGES],
              "    default:", "        return NULL;", "    }", "}", "",
              "#ifdef BRIDGE_MESSAGES_PRINT", "#include <stdio.h>",
              "/* A decoded message as one JSON line (tests compare it with the host's decoder). */",
              "static inline void bridge_print(FILE *out, const struct bridge_msg *msg)", "{",
              '    fprintf(out, "{\\"name\\": \\"%s\\", \\"seq\\": %u", bridge_msg_name(msg->id), (unsigned)msg->seq);',
              "    switch (msg->id) {"]
    for m in MESSAGES:
        lines += _printer(m)
    lines += ["    default:", "        break;", "    }", '    fprintf(out, "}\\n");', "}", "#endif", "", "#endif", ""]
    return "\n".join(lines)


def write(out: Path = OUT) -> Path:
    """Writes the header when its text changed (a build then recompiles only what needs it)."""
    return write_text_if_changed(out, header())


if __name__ == "__main__":
    print(write(Path(sys.argv[1]) if len(sys.argv) > 1 else OUT))
