-- Wireshark dissector for the robokey wire format, version 2 (docs/wire.md).
--
-- Use:  wireshark -X lua_script:contrib/wireshark/robokey.lua session.pcap
--       tshark -r session.pcap -X lua_script:contrib/wireshark/robokey.lua -Y robokey
-- Copy it into Wireshark's personal plugins folder to load it always. Frames are found on
-- any UDP port by their magic "RK" and version 2. The MAC is shown, not checked (that needs
-- the pairing secret).

local robokey = Proto("robokey", "robokey key agreement")

local MAC_BYTES = 16
local HEADER_BYTES = 16

local types = {
    [1] = "Hello", [2] = "HelloAck", [3] = "Measurement", [4] = "Command",
    [5] = "Finish", [6] = "FinishAck", [7] = "Confirm", [8] = "Abort",
    [9] = "Refuse", [10] = "Ready", [11] = "PrivateMeasurement", [12] = "DoubletCommand",
    [13] = "Done",
    [16] = "PostFragment", [17] = "reserved: post-processing", [18] = "reserved: post-processing",
    [19] = "reserved: post-processing", [20] = "reserved: post-processing",
    [21] = "reserved: post-processing",
}
local auth_modes = { [0] = "paired", [1] = "unauthenticated" }
local applied_flags = { [0] = "none", [1] = "present" }

local f = {
    magic = ProtoField.uint16("robokey.magic", "Magic", base.HEX),
    version = ProtoField.uint8("robokey.version", "Version", base.DEC),
    type = ProtoField.uint8("robokey.type", "Type", base.DEC, types),
    session = ProtoField.uint32("robokey.session", "Session", base.DEC),
    seq = ProtoField.uint32("robokey.seq", "Sequence number", base.DEC),
    step = ProtoField.uint32("robokey.step", "Step k", base.DEC),
    mac = ProtoField.bytes("robokey.mac", "MAC (HMAC-SHA256, 128 bits)"),
    auth = ProtoField.uint8("robokey.auth", "Pairing mode", base.DEC, auth_modes),
    nonce_c = ProtoField.bytes("robokey.nonce_c", "nonce_c"),
    nonce_r = ProtoField.bytes("robokey.nonce_r", "nonce_r"),
    digest = ProtoField.bytes("robokey.config_digest", "Configuration digest (SHA-256)"),
    text_len = ProtoField.uint16("robokey.text_len", "Text length", base.DEC),
    terms = ProtoField.string("robokey.terms", "Agreement terms"),
    reason = ProtoField.string("robokey.reason", "Reason"),
    px = ProtoField.double("robokey.y.px", "y: px (m)"),
    py = ProtoField.double("robokey.y.py", "y: py (m)"),
    theta = ProtoField.double("robokey.y.theta", "y: theta (rad)"),
    applied_flag = ProtoField.uint8("robokey.applied_flag", "Applied step", base.DEC, applied_flags),
    applied_step = ProtoField.uint32("robokey.applied_step", "Applied step k", base.DEC),
    fate_cursor = ProtoField.uint32("robokey.fate_cursor", "Fate cursor", base.DEC),
    u0_right = ProtoField.double("robokey.u0.right", "u0D: right wheel (rad/s)"),
    u0_left = ProtoField.double("robokey.u0.left", "u0D: left wheel (rad/s)"),
    u1_right = ProtoField.double("robokey.u1.right", "u1D: right wheel (rad/s)"),
    u1_left = ProtoField.double("robokey.u1.left", "u1D: left wheel (rad/s)"),
    fates_first = ProtoField.uint32("robokey.fates.first", "Fates: first codeword", base.DEC),
    fates_count = ProtoField.uint8("robokey.fates.count", "Fates: count", base.DEC),
    fates_accepted = ProtoField.uint64("robokey.fates.accepted", "Fates: accepted bitmap", base.HEX),
    codewords = ProtoField.uint32("robokey.codewords", "Codewords", base.DEC),
    bitmap_word = ProtoField.uint64("robokey.bitmap", "Fate bitmap word", base.HEX),
    session_tag = ProtoField.bytes("robokey.session_tag", "Session tag"),
    key_tag = ProtoField.bytes("robokey.key_tag", "Key tag"),
    sample_px = ProtoField.double("robokey.sample.px", "y_c: px (m)"),
    sample_py = ProtoField.double("robokey.sample.py", "y_c: py (m)"),
    sample_theta = ProtoField.double("robokey.sample.theta", "y_c: theta (rad)"),
    first_v = ProtoField.double("robokey.first.v", "u: v (m/s)"),
    first_omega = ProtoField.double("robokey.first.omega", "u: omega (rad/s)"),
    second_flag = ProtoField.uint8("robokey.second_flag", "Second input", base.DEC, applied_flags),
    second_v = ProtoField.double("robokey.second.v", "u': v (m/s)"),
    second_omega = ProtoField.double("robokey.second.omega", "u': omega (rad/s)"),
    post_message = ProtoField.uint32("robokey.post.message", "Post-processing message id", base.DEC),
    post_index = ProtoField.uint16("robokey.post.index", "Fragment index", base.DEC),
    post_count = ProtoField.uint16("robokey.post.count", "Fragment count", base.DEC),
    post_len = ProtoField.uint16("robokey.post.len", "Chunk length", base.DEC),
    post_bytes = ProtoField.bytes("robokey.post.bytes", "Chunk of the encoded message"),
}
robokey.fields = {
    f.magic, f.version, f.type, f.session, f.seq, f.step, f.mac, f.auth, f.nonce_c, f.nonce_r,
    f.digest, f.text_len, f.terms, f.reason, f.px, f.py, f.theta, f.applied_flag,
    f.applied_step, f.fate_cursor, f.u0_right, f.u0_left, f.u1_right, f.u1_left,
    f.fates_first, f.fates_count, f.fates_accepted, f.codewords, f.bitmap_word,
    f.session_tag, f.key_tag, f.sample_px, f.sample_py, f.sample_theta, f.first_v,
    f.first_omega, f.second_flag, f.second_v, f.second_omega, f.post_message, f.post_index,
    f.post_count, f.post_len, f.post_bytes,
}

-- A fate window (13 bytes) at payload offset `at`.
local function add_fates(t, p, at)
    t:add(f.fates_first, p(at, 4)); t:add(f.fates_count, p(at + 4, 1))
    t:add(f.fates_accepted, p(at + 5, 8))
end

local e_length = ProtoExpert.new("robokey.bad_length", "Payload length does not fit the type",
    expert.group.MALFORMED, expert.severity.ERROR)
local e_field = ProtoExpert.new("robokey.bad_field", "A field holds a value the protocol does not allow",
    expert.group.MALFORMED, expert.severity.ERROR)
robokey.experts = { e_length, e_field }

-- Adds `len u16 | UTF-8 text` at payload offset `at` (the rest of the payload) as `field`.
local function add_text(t, p, n, at, field)
    if n < at + 2 then return false end
    local len = p(at, 2):uint()
    t:add(f.text_len, p(at, 2))
    if n ~= at + 2 + len then return false end
    if len > 0 then t:add(field, p(at + 2, len), p(at + 2, len):string(ENC_UTF_8)) end
    return true
end

-- Each type's payload, given the tree `t`, `p(offset, length)` (a range of the payload) and
-- the payload length `n`; returns false when the length does not fit.
local payloads = {
    [1] = function(t, p, n)
        if n < 49 then return false end
        t:add(f.auth, p(0, 1)); t:add(f.nonce_c, p(1, 16)); t:add(f.digest, p(17, 32))
        return add_text(t, p, n, 49, f.terms)
    end,
    [2] = function(t, p, n)
        if n ~= 65 then return false end
        t:add(f.auth, p(0, 1)); t:add(f.nonce_c, p(1, 16)); t:add(f.nonce_r, p(17, 16))
        t:add(f.digest, p(33, 32))
        return true
    end,
    [3] = function(t, p, n)
        if n ~= 33 then return false end
        t:add(f.px, p(0, 8)); t:add(f.py, p(8, 8)); t:add(f.theta, p(16, 8))
        t:add(f.applied_flag, p(24, 1)); t:add(f.applied_step, p(25, 4))
        t:add(f.fate_cursor, p(29, 4))
        return true
    end,
    [4] = function(t, p, n)
        if n ~= 45 then return false end
        t:add(f.u0_right, p(0, 8)); t:add(f.u0_left, p(8, 8))
        t:add(f.u1_right, p(16, 8)); t:add(f.u1_left, p(24, 8))
        add_fates(t, p, 32)
        return true
    end,
    [5] = function(t, p, n)
        if n < 4 then return false end
        local codewords = p(0, 4):uint()
        t:add(f.codewords, p(0, 4))
        local words = math.floor((codewords + 63) / 64)
        if n ~= 4 + 8 * words then return false end
        for i = 0, words - 1 do t:add(f.bitmap_word, p(4 + 8 * i, 8)) end
        return true
    end,
    [6] = function(_, _, n) return n == 0 end,
    [13] = function(_, _, n) return n == 0 end,
    [7] = function(t, p, n)
        if n ~= 32 then return false end
        t:add(f.session_tag, p(0, 16)); t:add(f.key_tag, p(16, 16))
        return true
    end,
    [8] = function(t, p, n) return add_text(t, p, n, 0, f.reason) end,
    [9] = function(t, p, n)
        if n < 16 then return false end
        t:add(f.nonce_c, p(0, 16))
        return add_text(t, p, n, 16, f.reason)
    end,
    [10] = function(_, _, n) return n == 0 end,
    [11] = function(t, p, n)
        if n ~= 9 then return false end
        t:add(f.applied_flag, p(0, 1)); t:add(f.applied_step, p(1, 4))
        t:add(f.fate_cursor, p(5, 4))
        return true
    end,
    [12] = function(t, p, n)
        if n ~= 70 then return false end
        t:add(f.sample_px, p(0, 8)); t:add(f.sample_py, p(8, 8)); t:add(f.sample_theta, p(16, 8))
        t:add(f.first_v, p(24, 8)); t:add(f.first_omega, p(32, 8))
        t:add(f.second_flag, p(40, 1))
        if p(40, 1):uint() == 1 then
            t:add(f.second_v, p(41, 8)); t:add(f.second_omega, p(49, 8))
        end
        add_fates(t, p, 57)
        return true
    end,
    -- PostFragment: message u32 | index u16 | count u16 | len u16 | chunk; 1 <= count <= 1024,
    -- index < count, 1 <= len <= 1024.
    [16] = function(t, p, n)
        if n < 10 then return false end
        t:add(f.post_message, p(0, 4)); t:add(f.post_index, p(4, 2))
        t:add(f.post_count, p(6, 2)); t:add(f.post_len, p(8, 2))
        local index, count, len = p(4, 2):uint(), p(6, 2):uint(), p(8, 2):uint()
        if count < 1 or count > 1024 or index >= count or len < 1 or len > 1024 then
            t:add_proto_expert_info(e_field)
        end
        if n ~= 10 + len then return false end
        t:add(f.post_bytes, p(10, len))
        return true
    end,
}

local function dissect(tvb, pinfo, root)
    local len = tvb:len()
    if len < HEADER_BYTES + MAC_BYTES then return 0 end
    if tvb(0, 2):uint() ~= 0x524B or tvb(2, 1):uint() ~= 2 then return 0 end
    pinfo.cols.protocol = "robokey"
    local kind = tvb(3, 1):uint()
    local tree = root:add(robokey, tvb(), "robokey v2, " .. (types[kind] or "unknown type"))
    tree:add(f.magic, tvb(0, 2)); tree:add(f.version, tvb(2, 1)); tree:add(f.type, tvb(3, 1))
    tree:add(f.session, tvb(4, 4)); tree:add(f.seq, tvb(8, 4)); tree:add(f.step, tvb(12, 4))
    local payload_len = len - HEADER_BYTES - MAC_BYTES
    local info = string.format("%s session %08x seq %d", types[kind] or ("type " .. kind),
        tvb(4, 4):uint(), tvb(8, 4):uint())
    if kind == 3 or kind == 4 or kind == 11 or kind == 12 then info = info .. " step " .. tvb(12, 4):uint() end
    pinfo.cols.info = info
    local parse = payloads[kind]
    if parse then
        local function range(offset, length) return tvb(HEADER_BYTES + offset, length) end
        if not parse(tree, range, payload_len) then tree:add_proto_expert_info(e_length) end
    end
    tree:add(f.mac, tvb(len - MAC_BYTES, MAC_BYTES))
    return len
end

function robokey.dissector(tvb, pinfo, root)
    return dissect(tvb, pinfo, root)
end

local function heuristic(tvb, pinfo, root)
    return dissect(tvb, pinfo, root) > 0
end

robokey:register_heuristic("udp", heuristic)
