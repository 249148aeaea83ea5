#!/usr/bin/python3
"""make_commands.py DBC DURATION_S > commands.txt

Plans the command frames the guest injects with cansend while sempose runs, from the DBC
(nothing hard-coded but name patterns): select pattern set, re-acquire, and two bad frames
(wrong length; unknown command code). Output lines: "<delay_ms> <label> <ID>#<HEX>", the
delay counted from the previous line (the first from sempose's CAN socket being bound).
Finds: the command message (name ~ /command|cmd/), its code signal (VAL_ table or name ~
/^(cmd|command|opcode|code|type)/), codes by VAL_ name (/select|pattern|mag/, /re.?acq/),
a counter (/seq|counter/), pattern set (/pattern/, else /^(arg|value|param)/), magnification
step (/mag/), nm/px (unit "nm/px", else /nm/), set to 10 nm/px.
"""
import os
import sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dbc  # noqa: E402


def plan(db, duration_s):
    cmds = db.find(r"command|cmd")
    if not cmds:
        raise SystemExit("make_commands: no command message (name ~ command|cmd) in the DBC")
    msg = cmds[0]
    code = next((s for s in msg.signals if s.choices), None) or \
        msg.find_signal(r"^(cmd|command|opcode|code|type)")
    if code is None:
        raise SystemExit(f"make_commands: {msg.name} has no command-code signal")
    seq = msg.find_signal(r"seq|counter")
    pat = msg.find_signal(r"pattern") or msg.find_signal(r"^(arg|value|param)")
    mag = msg.find_signal(r"mag")
    nmpx = next((s for s in msg.signals if s.unit.replace(" ", "").lower() == "nm/px"), None) \
        or msg.find_signal(r"nm")
    sel_code = code.choice_value(r"select|pattern|mag") if code.choices else None
    acq_code = code.choice_value(r"re.?acq") if code.choices else None
    counter = [1]

    def frame(code_raw, extra):
        vals = {}
        data = bytearray(msg.length)
        code.insert(data, code_raw)
        if seq is not None:
            seq.insert(data, counter[0])
            counter[0] += 1
        for s, v in extra:
            if s is not None:
                s.insert(data, s.raw_from_phys(v))
        return dbc.cansend_string(msg, bytes(data))

    total_ms = int(duration_s * 1000)
    out = []
    if sel_code is not None:
        extra = [(pat, 1), (mag if mag is not pat else None, 0)]
        if nmpx is not None:
            v = 10.0 if nmpx.minimum <= 10.0 <= max(nmpx.maximum, 10.0) else (nmpx.minimum + nmpx.maximum) / 2
            extra.append((nmpx, v))
        out.append((int(total_ms * 0.2), "select_pattern_set_1", frame(sel_code, extra)))
    else:
        print("make_commands: no select-pattern code in the VAL_ table", file=sys.stderr)
    if acq_code is not None:
        out.append((int(total_ms * 0.15), "reacquire", frame(acq_code, [])))
    else:
        print("make_commands: no re-acquire code in the VAL_ table", file=sys.stderr)
    fid = f"{msg.frame_id:08X}" if msg.extended else f"{msg.frame_id:03X}"
    out.append((int(total_ms * 0.1), "bad_short_frame", f"{fid}#FF"))
    known = set(code.choices) if code.choices else set()
    unknown = next(v for v in range((1 << code.length) - 1, -1, -1) if v not in known)
    out.append((int(total_ms * 0.05), "bad_unknown_code", frame(unknown, [])))
    return msg, out


def main(argv):
    db = dbc.Database.load(argv[1])
    msg, out = plan(db, float(argv[2]))
    print(f"# command message {msg.name} (0x{msg.frame_id:X})")
    for d, label, f in out:
        print(d, label, f)
    print(f"make_commands: {len(out)} command frames planned on {msg.name}", file=sys.stderr)


if __name__ == "__main__":
    main(sys.argv)
