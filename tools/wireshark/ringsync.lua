-- ringsync.lua: Wireshark dissector for the ringsync ring protocol, wire format version 1.
--
-- The byte-level specification is docs/wire.md; the layouts below mirror the `field` modules
-- of crates/wire (header::field, lumped::field, lumped::feedback::field,
-- lumped::lumped_only::field, lumped::delay::field, command::field, response::field), and the
-- suite's tshark test
-- (crates/cli/tests/wireshark.rs) checks every field this file shows against the wire crate.
--
-- Install: copy this file into Wireshark's personal Lua plugins folder (Help > About
-- Wireshark > Folders > "Personal Lua Plugins", e.g. ~/.local/lib/wireshark/plugins/), or
-- run `tshark -X lua_script:ringsync.lua -r CAPTURE`. docs/wireshark.md says more.
--
-- How frames reach it:
--   * EtherType 0x88B5 (IEEE 802 local experimental EtherType 1). The type is shared with
--     anyone's experiments, so the protocol "ringsync_eth" registered there claims a frame
--     only when it checks as a ringsync PDU: version 1, a known kind, a payload length that
--     fits the kind (and its slot count), the declared bytes present and a matching CRC-32.
--     Anything else falls through to "Data". Preference "claim_bad_crc" also claims frames
--     that pass every check but the CRC (to look at corrupted frames).
--   * UDP (the runtime's loopback transport, ephemeral ports): a heuristic with the same
--     checks ("ringsync_udp"; Analyze > Enabled Protocols turns it off), and the ports of
--     preference "udp_ports".
--   * Decode As, on "Ethertype" and "UDP port": protocol "RingSync" always claims the
--     frame and reports what is wrong with it as expert information.
--
-- Every field is named ringsync.*; the Info column shows the frame's text form as
-- `Frame`'s Display in crates/wire prints it (docs/wire.md, "Text form").
--
-- Works with the Lua 5.2 of Wireshark 3.x/4.0 and the Lua 5.4 of Wireshark 4.2 and later.
-- Licence: MIT OR Apache-2.0, as the ringsync workspace.

local PLUGIN_VERSION = "1.0.0"

if set_plugin_info then
    set_plugin_info({
        version = PLUGIN_VERSION,
        description = "ringsync ring protocol (wire format version 1): EtherType 0x88B5 and UDP",
        repository = "tools/wireshark/ringsync.lua in the ringsync workspace",
    })
end

---------------------------------------------------------------------------------------------
-- Layout (docs/wire.md; crates/wire `field` modules). Offsets are 0-based: {offset, size}.
---------------------------------------------------------------------------------------------

local WIRE_VERSION = 1
local ETHERTYPE = 0x88B5
local MTU = 1500

local HEADER = {
    version = { 0, 1 },
    kind = { 1, 1 },
    flags = { 2, 1 },
    retry = { 3, 1 },
    cycle = { 4, 4 },
    seq = { 8, 2 },
    length = { 10, 2 },
}
local HEADER_LEN = 12
local CRC_LEN = 4

local LUMPED = {
    master_time = { 0, 8 },
    first_slot = { 8, 2 },
    slot_count = { 10, 2 },
}
local LUMPED_PREFIX_LEN = 12

local FEEDBACK = {
    position = { 0, 4 },
    velocity = { 4, 4 },
    sample_time = { 8, 8 },
    status = { 16, 2 },
    written = { 18, 1 },
    reserved = { 19, 1 },
}
local FEEDBACK_SLOT_LEN = 20

local LUMPED_ONLY = {
    desired_position = { 20, 4 },
    desired_velocity = { 24, 4 },
    command = { 28, 4 },
}
local LUMPED_ONLY_SLOT_LEN = 32

-- The delay slot (kind 5): residence [ns, slave's own clock], path delay [ns], the probe seq
-- the residence belongs to, marker (0 not written, 1 written, 2 written with a residence).
local DELAY = {
    residence = { 0, 4 },
    path_delay = { 4, 4 },
    residence_of = { 8, 2 },
    marker = { 10, 1 },
    reserved = { 11, 1 },
}
local DELAY_SLOT_LEN = 12
local DELAY_MARKER_MAX = 2
-- The markers' meanings (DelayMarker in crates/wire).
local DELAY_MARKER_NAME = {
    [0] = "not written",
    [1] = "written",
    [2] = "written with a residence",
}

local COMMAND = {
    target = { 0, 2 },
    link = { 2, 2 },
    command = { 4, 4 },
    sample_time = { 8, 8 },
}
local COMMAND_PAYLOAD_LEN = 16

local RESPONSE = {
    source = { 0, 2 },
    status = { 2, 2 },
    echo_cycle = { 4, 4 },
    position = { 8, 4 },
    velocity = { 12, 4 },
    sample_time = { 16, 8 },
    applied = { 24, 4 },
}
local RESPONSE_PAYLOAD_LEN = 28

local KIND_LUMPED, KIND_COMMAND, KIND_RESPONSE, KIND_LUMPED_ONLY, KIND_DELAY = 1, 2, 3, 4, 5

-- The kinds' names in the text form (FrameKind::name).
local KIND_NAME = {
    [KIND_LUMPED] = "lumped",
    [KIND_COMMAND] = "command",
    [KIND_RESPONSE] = "response",
    [KIND_LUMPED_ONLY] = "lumped-only",
    [KIND_DELAY] = "delay",
}

-- Slot length of a lumped kind (the kinds with the lumped layout: 1, 4 and 5).
local SLOT_LEN = {
    [KIND_LUMPED] = FEEDBACK_SLOT_LEN,
    [KIND_LUMPED_ONLY] = LUMPED_ONLY_SLOT_LEN,
    [KIND_DELAY] = DELAY_SLOT_LEN,
}

-- Whether `kind` has the lumped layout (payload prefix, then slots).
local function is_lumped(kind)
    return SLOT_LEN[kind] ~= nil
end

-- Most slots of `slot_len` bytes one lumped frame carries within the Ethernet MTU (73, 46,
-- 122).
local function slot_capacity(slot_len)
    return math.floor((MTU - HEADER_LEN - CRC_LEN - LUMPED_PREFIX_LEN) / slot_len)
end

-- Header flags and status bits, in bit order: {mask, filter suffix, name, meaning}.
local FLAGS = {
    { 0x01, "stop", "STOP", "the master orders a controlled stop of the whole group" },
    { 0x02, "torque_off", "TORQUE_OFF", "the target axis's drive cuts torque and stays off (latched)" },
    { 0x04, "brake", "BRAKE",
        "the target axis's drive (lumped-only frame: every drive) brakes on its own to standstill, then cuts torque (latched)" },
}
local FLAGS_DEFINED = 0x07

local STATUS = {
    { 0x0001, "fault", "FAULT", "the axis is in its safe state (0 V) after a fault" },
    { 0x0002, "saturated", "SATURATED", "the last command was clipped to the drive's range" },
    { 0x0004, "watchdog", "WATCHDOG", "no valid command arrived for W cycles" },
    { 0x0008, "clock_unlocked", "CLOCK_UNLOCKED", "the slave's clock servo has not locked to the master yet" },
    { 0x0010, "following_error", "FOLLOWING_ERROR", "the axis exceeded its following-error limit" },
    { 0x0020, "stopping", "STOPPING", "the axis is stopping on a controlled ramp" },
    { 0x0040, "torque_off", "TORQUE_OFF", "the drive's torque is off (latched)" },
    { 0x0080, "braking", "BRAKING", "the slave lost its master and brakes its axis to standstill on its own" },
}
local STATUS_DEFINED = 0x00FF
-- Status bits that deserve a warning in the expert information.
local STATUS_ALARM = 0x0001 + 0x0004 + 0x0010 + 0x0040 + 0x0080

---------------------------------------------------------------------------------------------
-- Bit operations and CRC-32 (IEEE 802.3 / zlib: reflected 0xEDB88320, init and final XOR
-- 0xFFFFFFFF). Lua 5.2 has bit32; Lua 5.3+ has native operators (compiled at load time so
-- that Lua 5.2 never parses them).
---------------------------------------------------------------------------------------------

local band, bxor, rshift
if bit32 then
    band, bxor, rshift = bit32.band, bit32.bxor, bit32.rshift
else
    band, bxor, rshift = load([[
        return function(a, b) return a & b end,
               function(a, b) return a ~ b end,
               function(a, n) return a >> n end
    ]])()
end

local CRC_TABLE = {}
for i = 0, 255 do
    local c = i
    for _ = 1, 8 do
        if band(c, 1) == 1 then
            c = bxor(0xEDB88320, rshift(c, 1))
        else
            c = rshift(c, 1)
        end
    end
    CRC_TABLE[i] = c
end

-- CRC-32 of bytes 1..n of the Lua string s.
local function crc32(s, n)
    local c = 0xFFFFFFFF
    for i = 1, n do
        c = bxor(CRC_TABLE[band(bxor(c, s:byte(i)), 0xFF)], rshift(c, 8))
    end
    return bxor(c, 0xFFFFFFFF)
end

-- Little-endian reads from the Lua string s at 0-based offset o (the caller checks bounds).
local function u8(s, o) return s:byte(o + 1) end
local function u16(s, o)
    local a, b = s:byte(o + 1, o + 2)
    return a + b * 256
end
local function u32(s, o)
    local a, b, c, d = s:byte(o + 1, o + 4)
    return a + b * 256 + c * 65536 + d * 16777216
end
-- Whether the little-endian binary32 at o is NaN or infinite (exponent bits all ones).
local function f32_nonfinite(s, o)
    local b2, b3 = s:byte(o + 3, o + 4)
    return b3 % 128 == 127 and b2 >= 128
end

-- The names of the set bits in bit order joined by "|", or "-" (the text form).
local function bit_names(bits, table_)
    local names = {}
    for _, b in ipairs(table_) do
        if band(bits, b[1]) ~= 0 then
            names[#names + 1] = b[3]
        end
    end
    if #names == 0 then
        return "-"
    end
    return table.concat(names, "|")
end

---------------------------------------------------------------------------------------------
-- Validation: the checks of Frame::validate (crates/wire), in the same order and with the
-- same texts. Returns nil for a valid PDU, else the first error's text.
---------------------------------------------------------------------------------------------

local function truncated(what, needed, got)
    return string.format("truncated %s: need %d bytes, got %d", what, needed, got)
end

local function payload_length_error(kind, expected, got)
    return string.format("bad payload length for a %s frame: expected %d bytes, header says %d",
        KIND_NAME[kind], expected, got)
end

local function bad_crc_text(carried, computed)
    return string.format("bad CRC-32: frame carries 0x%08x, contents give 0x%08x", carried, computed)
end

local function reserved_status_text(bits)
    return string.format("reserved status bits set: 0x%04x (allowed: 0x%04x)", bits, STATUS_DEFINED)
end

-- Frame::check_len: header, then the declared payload and CRC.
local function check_len(s, n)
    if n < HEADER_LEN then
        return truncated("header", HEADER_LEN, n)
    end
    local need = HEADER_LEN + u16(s, HEADER.length[1]) + CRC_LEN
    if n < need then
        return truncated("payload and CRC", need, n)
    end
    return nil
end

-- LumpedPayload::new_checked over the payload at `at` of length `len`.
local function check_lumped_prefix(s, kind, at, len)
    if len < LUMPED_PREFIX_LEN then
        return truncated("lumped payload prefix", LUMPED_PREFIX_LEN, len)
    end
    local slot_len = SLOT_LEN[kind]
    local first = u16(s, at + LUMPED.first_slot[1])
    local count = u16(s, at + LUMPED.slot_count[1])
    local capacity = slot_capacity(slot_len)
    if count > capacity then
        return string.format("slot count %d over capacity: one frame carries at most %d slots", count, capacity)
    end
    if first + count > 65535 then
        return string.format("slots %d+%d address slaves past 65535", first, count)
    end
    local expected = LUMPED_PREFIX_LEN + count * slot_len
    if len ~= expected then
        return payload_length_error(kind, expected, len)
    end
    return nil
end

-- The texts of a bad delay slot marker and of a delay slot's reserved byte
-- (Error::BadDelayMarker, Error::Reserved).
local function bad_marker_text(marker)
    return string.format("bad delay slot marker %d: expected 0, 1 or 2", marker)
end

local function delay_reserved_text(reserved)
    return string.format("reserved field delay slot byte 11 is %d, expected 0", reserved)
end

-- DelaySlotView::check of the delay slot at `at`: the marker, then the reserved byte.
local function check_delay_slot(s, at)
    local marker = u8(s, at + DELAY.marker[1])
    if marker > DELAY_MARKER_MAX then
        return bad_marker_text(marker)
    end
    local reserved = u8(s, at + DELAY.reserved[1])
    if reserved ~= 0 then
        return delay_reserved_text(reserved)
    end
    return nil
end

-- FeedbackSlotView::check (and LumpedOnlySlotView::check, DelaySlotView::check) of the slot
-- at `at`.
local function check_slot(s, kind, at)
    if kind == KIND_DELAY then
        return check_delay_slot(s, at)
    end
    local marker = u8(s, at + FEEDBACK.written[1])
    if marker > 1 then
        return string.format("bad written-this-cycle marker %d: expected 0 or 1", marker)
    end
    local reserved = u8(s, at + FEEDBACK.reserved[1])
    if reserved ~= 0 then
        return string.format("reserved field slot byte 19 is %d, expected 0", reserved)
    end
    local status = u16(s, at + FEEDBACK.status[1])
    if band(status, 0xFFFF - STATUS_DEFINED) ~= 0 then
        return reserved_status_text(status)
    end
    if kind == KIND_LUMPED_ONLY and f32_nonfinite(s, at + LUMPED_ONLY.command[1]) then
        return "slot command is not a finite number"
    end
    return nil
end

-- The payload's own checks, once the header and CRC are good.
local function check_payload(s, kind, len)
    local at = HEADER_LEN
    if is_lumped(kind) then
        local e = check_lumped_prefix(s, kind, at, len)
        if e then return e end
        local count = u16(s, at + LUMPED.slot_count[1])
        for k = 0, count - 1 do
            e = check_slot(s, kind, at + LUMPED_PREFIX_LEN + k * SLOT_LEN[kind])
            if e then return e end
        end
        return nil
    elseif kind == KIND_COMMAND then
        if len ~= COMMAND_PAYLOAD_LEN then
            return payload_length_error(kind, COMMAND_PAYLOAD_LEN, len)
        end
        if u16(s, at + COMMAND.target[1]) == 0 then
            return "bad slave address 0: expected 1..=65535"
        end
        if f32_nonfinite(s, at + COMMAND.command[1]) then
            return "command is not a finite number"
        end
        return nil
    else -- KIND_RESPONSE
        if len ~= RESPONSE_PAYLOAD_LEN then
            return payload_length_error(kind, RESPONSE_PAYLOAD_LEN, len)
        end
        if u16(s, at + RESPONSE.source[1]) == 0 then
            return "bad slave address 0: expected 1..=65535"
        end
        local status = u16(s, at + RESPONSE.status[1])
        if band(status, 0xFFFF - STATUS_DEFINED) ~= 0 then
            return reserved_status_text(status)
        end
        if f32_nonfinite(s, at + RESPONSE.applied[1]) then
            return "applied command is not a finite number"
        end
        return nil
    end
end

-- Frame::validate on the n bytes of s: nil when valid, else the first error's text.
local function validate(s, n)
    local e = check_len(s, n)
    if e then return e end
    local version = u8(s, HEADER.version[1])
    if version ~= WIRE_VERSION then
        return string.format("bad protocol version %d: this build speaks version %d", version, WIRE_VERSION)
    end
    local kind = u8(s, HEADER.kind[1])
    if not KIND_NAME[kind] then
        return string.format(
            "bad frame kind %d: expected 1 (lumped), 2 (command), 3 (response), 4 (lumped-only) or 5 (delay)",
            kind)
    end
    local flags = u8(s, HEADER.flags[1])
    if band(flags, 0xFF - FLAGS_DEFINED) ~= 0 then
        return string.format("reserved header flag bits set: 0x%02x (allowed: 0x%02x)", flags, FLAGS_DEFINED)
    end
    local len = u16(s, HEADER.length[1])
    local carried = u32(s, HEADER_LEN + len)
    local computed = crc32(s, HEADER_LEN + len)
    if carried ~= computed then
        return bad_crc_text(carried, computed)
    end
    return check_payload(s, kind, len)
end

-- The heuristic's question: is this a ringsync PDU? Version, kind, a payload length that
-- fits the kind, the declared bytes present, and (unless `bad_crc_ok`) the CRC.
local function looks_like_pdu(s, n, bad_crc_ok)
    if check_len(s, n) then return false end
    if u8(s, HEADER.version[1]) ~= WIRE_VERSION then return false end
    local kind = u8(s, HEADER.kind[1])
    if not KIND_NAME[kind] then return false end
    local len = u16(s, HEADER.length[1])
    if is_lumped(kind) then
        if check_lumped_prefix(s, kind, HEADER_LEN, len) then return false end
    elseif kind == KIND_COMMAND then
        if len ~= COMMAND_PAYLOAD_LEN then return false end
    elseif len ~= RESPONSE_PAYLOAD_LEN then
        return false
    end
    if bad_crc_ok then return true end
    return u32(s, HEADER_LEN + len) == crc32(s, HEADER_LEN + len)
end

---------------------------------------------------------------------------------------------
-- Protocol, fields, expert information
---------------------------------------------------------------------------------------------

local ringsync = Proto("ringsync", "RingSync ring protocol")

local function units(u) return { " " .. u } end

local hf = {
    version = ProtoField.uint8("ringsync.version", "Version", base.DEC, nil, nil,
        "Protocol version (1 in this version of the format)"),
    kind = ProtoField.uint8("ringsync.kind", "Kind", base.DEC, {
        [KIND_LUMPED] = "sync lumped frame",
        [KIND_COMMAND] = "command frame",
        [KIND_RESPONSE] = "response frame",
        [KIND_LUMPED_ONLY] = "lumped-only frame",
        [KIND_DELAY] = "delay frame",
    }, nil, "Frame kind: 1 sync lumped, 2 command, 3 response, 4 lumped-only, 5 delay"),
    flags = ProtoField.uint8("ringsync.flags", "Flags", base.HEX, nil, nil, "Header flags"),
    flags_reserved = ProtoField.uint8("ringsync.flags.reserved", "Reserved flag bits", base.HEX, nil,
        0xFF - FLAGS_DEFINED, "Bits 3-7, reserved (0)"),
    retry = ProtoField.uint8("ringsync.retry", "Retry", base.DEC, nil, nil,
        "0 for the first attempt, k for the k-th retry of the same exchange"),
    cycle = ProtoField.uint32("ringsync.cycle", "Cycle", base.DEC, nil, nil,
        "Cycle counter of the sender (wraps)"),
    seq = ProtoField.uint16("ringsync.seq", "Sequence number", base.DEC, nil, nil,
        "Sequence number of the sender (wraps), one per PDU sent"),
    length = ProtoField.uint16("ringsync.length", "Payload length", base.UNIT_STRING, units("bytes"),
        nil, "Bytes between header and CRC"),
    payload = ProtoField.bytes("ringsync.payload", "Payload", base.NONE, "Payload bytes (undecoded)"),
    crc = ProtoField.uint32("ringsync.crc", "CRC-32", base.HEX, nil, nil,
        "CRC-32 (IEEE 802.3) over header and payload"),
    crc_status = ProtoField.uint8("ringsync.crc.status", "CRC-32 status", base.DEC,
        { [0] = "Bad", [1] = "Good", [2] = "Unverified" }, nil, "Whether the CRC-32 matches the contents"),
    crc_computed = ProtoField.uint32("ringsync.crc.computed", "Computed CRC-32", base.HEX, nil, nil,
        "CRC-32 computed over header and payload"),
    padding = ProtoField.bytes("ringsync.padding", "Padding", base.NONE,
        "Bytes after the CRC (Ethernet padding), ignored by receivers"),
    slave = ProtoField.uint16("ringsync.slave", "Slave", base.DEC, nil, nil,
        "The slave a command goes to, a response comes from, or a slot belongs to"),

    -- Lumped frames (kinds 1, 4 and 5)
    master_time = ProtoField.uint64("ringsync.master_time", "Master send timestamp", base.UNIT_STRING,
        units("ns"), nil, "Send time of the lumped or delay frame on the master's clock [ns]"),
    first_slot = ProtoField.uint16("ringsync.first_slot", "First slot index", base.DEC, nil, nil,
        "Slot k of this frame belongs to slave first slot + k + 1"),
    slot_count = ProtoField.uint16("ringsync.slot_count", "Slot count", base.DEC, nil, nil,
        "Number of slots in the frame"),
    slot = ProtoField.none("ringsync.slot", "Slot", base.NONE, "One slave's slot"),
    slot_index = ProtoField.uint16("ringsync.slot.index", "Slot index", base.DEC, nil, nil,
        "First slot index + k"),
    slot_position = ProtoField.int32("ringsync.slot.position", "Position", base.UNIT_STRING, units("counts"),
        nil, "Encoder counts, sampled at the synchronised sampling instant"),
    slot_velocity = ProtoField.int32("ringsync.slot.velocity", "Velocity", base.UNIT_STRING, units("counts/s"),
        nil, "Measured by the slave [counts/s]"),
    slot_sample_time = ProtoField.uint64("ringsync.slot.sample_time", "Sampling timestamp", base.UNIT_STRING,
        units("ns"), nil, "Sampling instant on the slave's synchronised clock [ns]"),
    slot_status = ProtoField.uint16("ringsync.slot.status", "Status", base.HEX, nil, nil, "Status bits"),
    slot_written = ProtoField.uint8("ringsync.slot.written", "Written", base.DEC,
        { [0] = "older values (not written in this cycle)", [1] = "written by the slave in this cycle" },
        nil, "1: written by the slave in this cycle; 0: the values are older (or empty)"),
    slot_reserved = ProtoField.uint8("ringsync.slot.reserved", "Reserved", base.DEC, nil, nil, "Reserved (0)"),
    slot_desired_position = ProtoField.int32("ringsync.slot.desired_position", "Desired position",
        base.UNIT_STRING, units("counts"), nil, "Written by the master [encoder counts]"),
    slot_desired_velocity = ProtoField.int32("ringsync.slot.desired_velocity", "Desired velocity",
        base.UNIT_STRING, units("counts/s"), nil, "Written by the master [counts/s]"),
    slot_command = ProtoField.float("ringsync.slot.command", "Command",
        "Written by the slave: the command it applied [V]"),

    -- Delay slots (kind 5)
    slot_residence = ProtoField.uint32("ringsync.slot.residence", "Residence", base.UNIT_STRING,
        units("ns"), nil, "How long the slave held probe 'residence of', first bit in to first bit out "
            .. "[ns, slave's own clock]"),
    slot_path_delay = ProtoField.uint32("ringsync.slot.path_delay", "Path delay", base.UNIT_STRING,
        units("ns"), nil, "Master send to the slave's first bit in [ns]; written by the master in a "
            .. "closing frame, 0 in a probe"),
    slot_residence_of = ProtoField.uint16("ringsync.slot.residence_of", "Residence of probe", base.DEC, nil,
        nil, "Header sequence number of the probe whose residence the slot reports"),
    slot_marker = ProtoField.uint8("ringsync.slot.marker", "Marker", base.DEC, DELAY_MARKER_NAME, nil,
        "0: not written; 1: written (no residence to report, or a closing frame's path delay taken); "
            .. "2: written with a residence"),

    -- Command frames (kind 2)
    command_target = ProtoField.uint16("ringsync.command.target", "Target slave", base.DEC, nil, nil,
        "1..=65535 (0 is the master and is rejected)"),
    command_link = ProtoField.uint16("ringsync.command.link", "Link delay", base.UNIT_STRING, units("ns"), nil,
        "The master's running estimate of one link behind transparent relays [ns]; 0: none"),
    command_value = ProtoField.float("ringsync.command.value", "Command",
        "Command for the drive [V]; the slave clips it to its drive's range"),
    command_sample_time = ProtoField.uint64("ringsync.command.sample_time", "Sampling instant",
        base.UNIT_STRING, units("ns"), nil,
        "Master clock [ns]: the feedback the command was computed from"),

    -- Response frames (kind 3)
    response_source = ProtoField.uint16("ringsync.response.source", "Source slave", base.DEC, nil, nil,
        "1..=65535"),
    response_status = ProtoField.uint16("ringsync.response.status", "Status", base.HEX, nil, nil, "Status bits"),
    response_echo_cycle = ProtoField.uint32("ringsync.response.echo_cycle", "Echo cycle", base.DEC, nil, nil,
        "Cycle of the command being answered"),
    response_position = ProtoField.int32("ringsync.response.position", "Position", base.UNIT_STRING,
        units("counts"), nil, "Encoder counts"),
    response_velocity = ProtoField.int32("ringsync.response.velocity", "Velocity", base.UNIT_STRING,
        units("counts/s"), nil, "Counts/s"),
    response_sample_time = ProtoField.uint64("ringsync.response.sample_time", "Measuring instant",
        base.UNIT_STRING, units("ns"), nil, "Slave's synchronised clock [ns]"),
    response_applied = ProtoField.float("ringsync.response.applied", "Applied command",
        "After clipping [V]"),
}

local hf_flag = {}
for _, b in ipairs(FLAGS) do
    hf_flag[b[1]] = ProtoField.bool("ringsync.flags." .. b[2], b[3], 8, nil, b[1], b[4])
end
local hf_status = {}
for _, b in ipairs(STATUS) do
    hf_status[b[1]] = ProtoField.bool("ringsync.status." .. b[2], b[3], 16, nil, b[1], b[4])
end
local hf_status_reserved = ProtoField.uint16("ringsync.status.reserved", "Reserved status bits", base.HEX,
    nil, 0xFFFF - STATUS_DEFINED, "Bits 8-15, reserved (0)")

do
    local all = {}
    for _, f in pairs(hf) do all[#all + 1] = f end
    for _, f in pairs(hf_flag) do all[#all + 1] = f end
    for _, f in pairs(hf_status) do all[#all + 1] = f end
    all[#all + 1] = hf_status_reserved
    ringsync.fields = all
end

local ei = {
    crc_bad = ProtoExpert.new("ringsync.crc.bad", "Bad CRC-32", expert.group.CHECKSUM, expert.severity.ERROR),
    truncated = ProtoExpert.new("ringsync.truncated", "Truncated PDU", expert.group.MALFORMED,
        expert.severity.ERROR),
    version = ProtoExpert.new("ringsync.version.bad", "Unknown protocol version", expert.group.MALFORMED,
        expert.severity.ERROR),
    kind = ProtoExpert.new("ringsync.kind.bad", "Unknown frame kind", expert.group.MALFORMED,
        expert.severity.ERROR),
    length = ProtoExpert.new("ringsync.length.bad", "Payload length does not fit the frame kind",
        expert.group.MALFORMED, expert.severity.ERROR),
    slots = ProtoExpert.new("ringsync.slots.bad", "Slot count over capacity or slots past slave 65535",
        expert.group.MALFORMED, expert.severity.ERROR),
    reserved = ProtoExpert.new("ringsync.reserved", "Reserved bits or field not zero",
        expert.group.PROTOCOL, expert.severity.ERROR),
    address = ProtoExpert.new("ringsync.slave.bad", "Slave address 0 (the master's)",
        expert.group.PROTOCOL, expert.severity.ERROR),
    marker = ProtoExpert.new("ringsync.slot.written.bad", "Written marker other than 0 or 1",
        expert.group.PROTOCOL, expert.severity.ERROR),
    delay_marker = ProtoExpert.new("ringsync.slot.marker.bad", "Delay-slot marker other than 0, 1 or 2",
        expert.group.PROTOCOL, expert.severity.ERROR),
    nonfinite = ProtoExpert.new("ringsync.nonfinite", "Not a finite number", expert.group.PROTOCOL,
        expert.severity.ERROR),
    internal = ProtoExpert.new("ringsync.internal", "Dissector error (please report)", expert.group.MALFORMED,
        expert.severity.ERROR),
    order = ProtoExpert.new("ringsync.flags.order", "The master orders a stop, torque off or brake",
        expert.group.REQUEST_CODE, expert.severity.WARN),
    retry = ProtoExpert.new("ringsync.retry.note", "Retry of an exchange", expert.group.SEQUENCE,
        expert.severity.NOTE),
    alarm = ProtoExpert.new("ringsync.status.alarm", "A slave reports a fault, watchdog, following error, "
        .. "torque off or braking", expert.group.RESPONSE_CODE, expert.severity.WARN),
}
ringsync.experts = {
    ei.crc_bad, ei.truncated, ei.version, ei.kind, ei.length, ei.slots, ei.reserved, ei.address,
    ei.marker, ei.delay_marker, ei.nonfinite, ei.internal, ei.order, ei.retry, ei.alarm,
}

ringsync.prefs.claim_bad_crc = Pref.bool("Claim EtherType 0x88B5 frames with a bad CRC-32", false,
    "Also claim EtherType 0x88B5 frames that pass every check but the CRC-32, and show them with a "
        .. "bad-CRC expert info (EtherType 0x88B5 is shared: off by default)")
ringsync.prefs.udp_ports = Pref.range("UDP ports", "",
    "UDP ports always decoded as RingSync. The runtime's loopback ring uses ephemeral ports, which "
        .. "the UDP heuristic finds; Decode As works too.", 65535)

---------------------------------------------------------------------------------------------
-- Dissection
---------------------------------------------------------------------------------------------

-- Adds the value at payload offset `at` of field hf_ with its layout entry; little-endian.
local function add(tree, field, tvb, at, layout)
    return tree:add_le(field, tvb(at + layout[1], layout[2]))
end

local function add_status(tree, field, tvb, at, slave)
    local range = tvb(at, 2)
    local bits = range:le_uint()
    local item = tree:add_le(field, range)
    item:append_text(" (" .. bit_names(bits, STATUS) .. ")")
    for _, b in ipairs(STATUS) do
        item:add_le(hf_status[b[1]], range)
    end
    item:add_le(hf_status_reserved, range)
    if band(bits, 0xFFFF - STATUS_DEFINED) ~= 0 then
        item:add_proto_expert_info(ei.reserved, reserved_status_text(bits))
    end
    if band(bits, STATUS_ALARM) ~= 0 then
        item:add_proto_expert_info(ei.alarm, string.format("slave %d: %s", slave,
            bit_names(band(bits, STATUS_ALARM), STATUS)))
    end
    return bits
end

-- A binary32 in volts (the unit is appended here: Wireshark 4.0 has no unit for floats).
local function add_float(tree, field, tvb, at, what)
    local item = tree:add_le(field, tvb(at, 4))
    item:append_text(" V")
    if f32_nonfinite(tvb:raw(at, 4), 0) then
        item:add_proto_expert_info(ei.nonfinite, what .. " is not a finite number")
    end
    return item
end

local function fmt_v(range)
    return string.format("%.3f", range:le_float())
end

-- The fields of one delay slot (kind 5) at tvb offset `at` into the slot's subtree `st`.
local function dissect_delay_slot(tvb, st, at, index, slave)
    local residence = tvb(at + DELAY.residence[1], 4):le_uint()
    local path_delay = tvb(at + DELAY.path_delay[1], 4):le_uint()
    local residence_of = tvb(at + DELAY.residence_of[1], 2):le_uint()
    local marker = tvb(at + DELAY.marker[1], 1):uint()
    add(st, hf.slot_residence, tvb, at, DELAY.residence)
    add(st, hf.slot_path_delay, tvb, at, DELAY.path_delay)
    add(st, hf.slot_residence_of, tvb, at, DELAY.residence_of)
    local m = add(st, hf.slot_marker, tvb, at, DELAY.marker)
    if marker > DELAY_MARKER_MAX then
        m:add_proto_expert_info(ei.delay_marker, bad_marker_text(marker))
    end
    local r = add(st, hf.slot_reserved, tvb, at, DELAY.reserved)
    local reserved = tvb(at + DELAY.reserved[1], 1):uint()
    if reserved ~= 0 then
        r:add_proto_expert_info(ei.reserved, delay_reserved_text(reserved))
    end
    local text = string.format("Slot %d, slave %d: %s", index, slave,
        DELAY_MARKER_NAME[marker] or string.format("bad marker %d", marker))
    if marker == 2 then
        text = text .. string.format(", residence %d ns of probe %d", residence, residence_of)
    end
    if path_delay ~= 0 then
        text = text .. string.format(", path delay %d ns", path_delay)
    end
    st:set_text(text)
end

-- One slot of a lumped frame at tvb offset `at`: a subtree.
local function dissect_slot(tvb, tree, kind, at, index)
    local slot_len = SLOT_LEN[kind]
    local slave = index + 1
    local st = tree:add(hf.slot, tvb(at, slot_len))
    st:add(hf.slot_index, tvb(at, slot_len), index):set_generated()
    st:add(hf.slave, tvb(at, slot_len), slave):set_generated()
    if kind == KIND_DELAY then
        dissect_delay_slot(tvb, st, at, index, slave)
        return
    end
    local pos = tvb(at + FEEDBACK.position[1], 4):le_int()
    local written = tvb(at + FEEDBACK.written[1], 1):uint()
    add(st, hf.slot_position, tvb, at, FEEDBACK.position)
    add(st, hf.slot_velocity, tvb, at, FEEDBACK.velocity)
    add(st, hf.slot_sample_time, tvb, at, FEEDBACK.sample_time)
    local status = add_status(st, hf.slot_status, tvb, at + FEEDBACK.status[1], slave)
    local w = add(st, hf.slot_written, tvb, at, FEEDBACK.written)
    if written > 1 then
        w:add_proto_expert_info(ei.marker, string.format("bad written-this-cycle marker %d: expected 0 or 1",
            written))
    end
    local r = add(st, hf.slot_reserved, tvb, at, FEEDBACK.reserved)
    local reserved = tvb(at + FEEDBACK.reserved[1], 1):uint()
    if reserved ~= 0 then
        r:add_proto_expert_info(ei.reserved, string.format("reserved field slot byte 19 is %d, expected 0",
            reserved))
    end
    local text = string.format("Slot %d, slave %d: position %d counts, status %s, %s", index, slave, pos,
        bit_names(status, STATUS), written == 1 and "written" or "not written")
    if kind == KIND_LUMPED_ONLY then
        add(st, hf.slot_desired_position, tvb, at, LUMPED_ONLY.desired_position)
        add(st, hf.slot_desired_velocity, tvb, at, LUMPED_ONLY.desired_velocity)
        add_float(st, hf.slot_command, tvb, at + LUMPED_ONLY.command[1], "slot command")
        text = text .. string.format(", desired %d counts, command %s V",
            tvb(at + LUMPED_ONLY.desired_position[1], 4):le_int(), fmt_v(tvb(at + LUMPED_ONLY.command[1], 4)))
    end
    st:set_text(text)
end

-- The payload of a lumped frame (kind 1, 4 or 5) at tvb offset `at`, `len` bytes declared, of
-- which `avail` are in the buffer. Returns the summary for the text form.
local function dissect_lumped(tvb, tree, kind, at, len, avail)
    if avail < LUMPED_PREFIX_LEN then
        return nil
    end
    local first = tvb(at + LUMPED.first_slot[1], 2):le_uint()
    local count = tvb(at + LUMPED.slot_count[1], 2):le_uint()
    local master_time = tvb(at + LUMPED.master_time[1], 8):le_uint64()
    add(tree, hf.master_time, tvb, at, LUMPED.master_time)
    add(tree, hf.first_slot, tvb, at, LUMPED.first_slot)
    local ci = add(tree, hf.slot_count, tvb, at, LUMPED.slot_count)
    local slot_len = SLOT_LEN[kind]
    local capacity = slot_capacity(slot_len)
    if count > capacity then
        ci:add_proto_expert_info(ei.slots, string.format(
            "slot count %d over capacity: one frame carries at most %d slots", count, capacity))
    elseif first + count > 65535 then
        ci:add_proto_expert_info(ei.slots, string.format("slots %d+%d address slaves past 65535", first, count))
    end
    for k = 0, count - 1 do
        local off = LUMPED_PREFIX_LEN + k * slot_len
        if off + slot_len > avail then
            break
        end
        dissect_slot(tvb, tree, kind, at + off, first + k)
    end
    return string.format(", slots %d..%d, sent at %s ns", first, first + count, tostring(master_time))
end

local function dissect_command(tvb, tree, at)
    local target = tvb(at + COMMAND.target[1], 2):le_uint()
    local t = add(tree, hf.command_target, tvb, at, COMMAND.target)
    tree:add(hf.slave, tvb(at + COMMAND.target[1], 2), target):set_generated()
    if target == 0 then
        t:add_proto_expert_info(ei.address, "bad slave address 0: expected 1..=65535")
    end
    add(tree, hf.command_link, tvb, at, COMMAND.link)
    add_float(tree, hf.command_value, tvb, at + COMMAND.command[1], "command")
    add(tree, hf.command_sample_time, tvb, at, COMMAND.sample_time)
    local link = tvb(at + COMMAND.link[1], 2):le_uint()
    local link_text = ""
    if link ~= 0 then
        link_text = string.format(", link %d ns", link)
    end
    return string.format(" → slave %d: %s V, sampled at %s ns%s", target, fmt_v(tvb(at + COMMAND.command[1], 4)),
        tostring(tvb(at + COMMAND.sample_time[1], 8):le_uint64()), link_text)
end

local function dissect_response(tvb, tree, at)
    local source = tvb(at + RESPONSE.source[1], 2):le_uint()
    local s = add(tree, hf.response_source, tvb, at, RESPONSE.source)
    tree:add(hf.slave, tvb(at + RESPONSE.source[1], 2), source):set_generated()
    if source == 0 then
        s:add_proto_expert_info(ei.address, "bad slave address 0: expected 1..=65535")
    end
    local status = add_status(tree, hf.response_status, tvb, at + RESPONSE.status[1], source)
    add(tree, hf.response_echo_cycle, tvb, at, RESPONSE.echo_cycle)
    add(tree, hf.response_position, tvb, at, RESPONSE.position)
    add(tree, hf.response_velocity, tvb, at, RESPONSE.velocity)
    add(tree, hf.response_sample_time, tvb, at, RESPONSE.sample_time)
    add_float(tree, hf.response_applied, tvb, at + RESPONSE.applied[1], "applied command")
    return string.format(
        " from slave %d: status %s, echo cycle %d, position %d counts, velocity %d counts/s, "
            .. "sampled at %s ns, applied %s V",
        source, bit_names(status, STATUS), tvb(at + RESPONSE.echo_cycle[1], 4):le_uint(),
        tvb(at + RESPONSE.position[1], 4):le_int(), tvb(at + RESPONSE.velocity[1], 4):le_int(),
        tostring(tvb(at + RESPONSE.sample_time[1], 8):le_uint64()),
        fmt_v(tvb(at + RESPONSE.applied[1], 4)))
end

-- Dissects the PDU at the start of tvb into `tree`; returns the bytes it covers.
local function dissect_pdu(tvb, pinfo, tree)
    local n = tvb:len()
    local s = tvb:raw(0, n)
    pinfo.cols.protocol:set("RingSync")
    local problem = validate(s, n)

    local root = tree:add(ringsync, tvb(0, n))
    if n < HEADER_LEN then
        root:add_proto_expert_info(ei.truncated, problem)
        local text = "bad frame (" .. problem .. ")"
        root:append_text(", " .. text)
        pinfo.cols.info:set(text)
        return n
    end

    -- Header
    local version = u8(s, HEADER.version[1])
    local kind = u8(s, HEADER.kind[1])
    local flags = u8(s, HEADER.flags[1])
    local retry = u8(s, HEADER.retry[1])
    local cycle = u32(s, HEADER.cycle[1])
    local seq = u16(s, HEADER.seq[1])
    local len = u16(s, HEADER.length[1])
    local vi = add(root, hf.version, tvb, 0, HEADER.version)
    if version ~= WIRE_VERSION then
        vi:add_proto_expert_info(ei.version, string.format(
            "bad protocol version %d: this build speaks version %d", version, WIRE_VERSION))
    end
    local ki = add(root, hf.kind, tvb, 0, HEADER.kind)
    if not KIND_NAME[kind] then
        ki:add_proto_expert_info(ei.kind, string.format(
            "bad frame kind %d: expected 1 (lumped), 2 (command), 3 (response), 4 (lumped-only) or 5 (delay)",
            kind))
    end
    local fi = add(root, hf.flags, tvb, 0, HEADER.flags)
    fi:append_text(" (" .. bit_names(flags, FLAGS) .. ")")
    for _, b in ipairs(FLAGS) do
        fi:add(hf_flag[b[1]], tvb(HEADER.flags[1], 1))
    end
    fi:add(hf.flags_reserved, tvb(HEADER.flags[1], 1))
    if band(flags, 0xFF - FLAGS_DEFINED) ~= 0 then
        fi:add_proto_expert_info(ei.reserved, string.format(
            "reserved header flag bits set: 0x%02x (allowed: 0x%02x)", flags, FLAGS_DEFINED))
    elseif flags ~= 0 then
        fi:add_proto_expert_info(ei.order, "the master orders " .. bit_names(flags, FLAGS))
    end
    local ri = add(root, hf.retry, tvb, 0, HEADER.retry)
    if retry ~= 0 then
        ri:add_proto_expert_info(ei.retry, string.format("retry %d", retry))
    end
    add(root, hf.cycle, tvb, 0, HEADER.cycle)
    add(root, hf.seq, tvb, 0, HEADER.seq)
    local li = add(root, hf.length, tvb, 0, HEADER.length)

    -- Payload
    local pdu_len = HEADER_LEN + len + CRC_LEN
    local avail = math.min(len, n - HEADER_LEN)
    local summary
    if KIND_NAME[kind] then
        local fits = true
        if kind == KIND_COMMAND then
            fits = len == COMMAND_PAYLOAD_LEN
        elseif kind == KIND_RESPONSE then
            fits = len == RESPONSE_PAYLOAD_LEN
        elseif len < LUMPED_PREFIX_LEN then
            fits = false
            li:add_proto_expert_info(ei.length, truncated("lumped payload prefix", LUMPED_PREFIX_LEN, len))
        elseif avail >= LUMPED_PREFIX_LEN then
            -- (Slot count over capacity and slots past 65535 show on the slot count.)
            local e = check_lumped_prefix(s, kind, HEADER_LEN, len)
            if e and e:find("^bad payload length") then
                fits = false
                li:add_proto_expert_info(ei.length, e)
            end
        end
        if (kind == KIND_COMMAND or kind == KIND_RESPONSE) and not fits then
            local expected = kind == KIND_COMMAND and COMMAND_PAYLOAD_LEN or RESPONSE_PAYLOAD_LEN
            li:add_proto_expert_info(ei.length, payload_length_error(kind, expected, len))
        end
        if fits and n >= pdu_len then
            if is_lumped(kind) then
                summary = dissect_lumped(tvb, root, kind, HEADER_LEN, len, avail)
            elseif kind == KIND_COMMAND then
                summary = dissect_command(tvb, root, HEADER_LEN)
            else
                summary = dissect_response(tvb, root, HEADER_LEN)
            end
        elseif is_lumped(kind) then
            -- Show the slots that are there.
            dissect_lumped(tvb, root, kind, HEADER_LEN, len, avail)
        elseif avail > 0 then
            root:add(hf.payload, tvb(HEADER_LEN, avail))
        end
    elseif avail > 0 then
        root:add(hf.payload, tvb(HEADER_LEN, avail))
    end

    -- Trailer
    if n < pdu_len then
        root:add_proto_expert_info(ei.truncated, truncated("payload and CRC", pdu_len, n))
    else
        local carried = u32(s, HEADER_LEN + len)
        local computed = crc32(s, HEADER_LEN + len)
        local crc_item = root:add_le(hf.crc, tvb(HEADER_LEN + len, CRC_LEN))
        local good = carried == computed
        crc_item:append_text(good and " [correct]" or string.format(" [incorrect, should be 0x%08x]", computed))
        crc_item:add(hf.crc_computed, tvb(HEADER_LEN + len, CRC_LEN), computed):set_generated()
        crc_item:add(hf.crc_status, tvb(HEADER_LEN + len, CRC_LEN), good and 1 or 0):set_generated()
        if not good then
            crc_item:add_proto_expert_info(ei.crc_bad, bad_crc_text(carried, computed))
        end
        if n > pdu_len then
            root:add(hf.padding, tvb(pdu_len, n - pdu_len))
        end
        root:set_len(pdu_len)
    end

    local text
    if problem then
        text = "bad frame (" .. problem .. ")"
    else
        text = string.format("%s cycle %d seq %d", KIND_NAME[kind], cycle, seq)
        if retry ~= 0 then
            text = text .. string.format(" retry %d", retry)
        end
        if flags ~= 0 then
            text = text .. " flags " .. bit_names(flags, FLAGS)
        end
        text = text .. summary
    end
    root:append_text(", " .. text)
    pinfo.cols.info:set(text)
    return math.min(n, pdu_len)
end

-- Dissects, turning a Lua error (a bug here) into expert information rather than an
-- exception, and returns the bytes covered.
local function dissect_safely(tvb, pinfo, tree)
    local ok, r = pcall(dissect_pdu, tvb, pinfo, tree)
    if ok then
        return r
    end
    local text = "ringsync.lua: " .. tostring(r)
    tree:add(ringsync, tvb()):add_proto_expert_info(ei.internal, text)
    pinfo.cols.info:set(text)
    return tvb:len()
end

-- Decode As (Ethertype, UDP port) and the UDP ports preference: always claims the frame.
function ringsync.dissector(tvb, pinfo, tree)
    return dissect_safely(tvb, pinfo, tree)
end

-- UDP heuristic: claims only a datagram that checks as a ringsync PDU (CRC included).
local function heur_udp(tvb, pinfo, tree)
    local n = tvb:len()
    if n < HEADER_LEN + CRC_LEN or not looks_like_pdu(tvb:raw(0, n), n, false) then
        return false
    end
    dissect_safely(tvb, pinfo, tree)
    return true
end
ringsync:register_heuristic("udp", heur_udp)

-- EtherType 0x88B5: a checking protocol of its own, so that the claim can be turned off
-- (Analyze > Enabled Protocols) and Decode As still offers the claiming one.
local ringsync_eth = Proto("ringsync_eth", "RingSync on EtherType 0x88B5 (claims checked PDUs only)")
local ringsync_handle
function ringsync_eth.dissector(tvb, pinfo, tree)
    local n = tvb:len()
    if n < HEADER_LEN + CRC_LEN or not looks_like_pdu(tvb:raw(0, n), n, ringsync.prefs.claim_bad_crc) then
        return 0
    end
    ringsync_handle = ringsync_handle or Dissector.get("ringsync")
    return ringsync_handle:call(tvb, pinfo, tree)
end

local ethertype_table = DissectorTable.get("ethertype")
ethertype_table:add(ETHERTYPE, ringsync_eth)
ethertype_table:add_for_decode_as(ringsync)
local udp_table = DissectorTable.get("udp.port")
udp_table:add_for_decode_as(ringsync)

local udp_ports = ""
function ringsync.prefs_changed()
    if udp_ports ~= "" then
        udp_table:remove(udp_ports, ringsync)
    end
    udp_ports = ringsync.prefs.udp_ports
    if udp_ports ~= "" then
        udp_table:add(udp_ports, ringsync)
    end
end
