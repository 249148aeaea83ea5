#!/usr/bin/python3
"""Writes ipc/sempose.dbc for a given CAN id base (the checked-in file uses the default 0x100).

    /usr/bin/python3 ipc/tools/make_dbc.py [--base 0x100] [--command-id 0x150] > my.dbc

A deployment that moves base_id / command_id in the config regenerates its DBC with this, so
the ids in the DBC always match what sempose sends. The layout must follow
ipc/include/sempose/ipc/protocol.hpp; tests/ipc decodes the C++ encoder's frames with the
checked-in DBC, so a mismatch fails a test.
"""
import argparse

TARGETS = 4
BLOCK = 0x10

# The DBC's VERSION: "sempose-<n>", n = ipc::kWireVersion (protocol.hpp; tests/ipc checks both).
WIRE_VERSION = 2

ANGLE_ORDER = ("Rotational order n of the target's pattern (it looks the same turned by 360/n deg): phi is known modulo 360/n deg only, and a TRACKING pose reports the look nearest the last angle. 1: phi is absolute; 2: phi or phi+180 (a lamella); 0: not said (an order above 7)")

# (name, start, length, signed, factor, offset, min, max, unit, comment)
POSE_XY = [
    ("x", 0, 28, True, 1, 0, -134217728, 134217727, "nm", "Pattern centre x in the scan field (saturating)"),
    ("y", 28, 28, True, 1, 0, -134217728, 134217727, "nm", "Pattern centre y, image y down (saturating)"),
    ("seq", 56, 8, False, 1, 0, 0, 255, "", "Pose sequence counter (low 8 bits), same in POSE_ATTR"),
]
POSE_ATTR = [
    ("phi", 0, 19, True, 0.001, 0, -180, 180, "deg", "Orientation, counter-clockwise positive, (-180, 180]"),
    ("score", 19, 11, True, 0.001, 0, -1, 1, "", "ZNCC peak score"),
    ("state", 30, 2, False, 1, 0, 0, 3, "", "0 TRACKING, 1 ACQUIRING, 2 LOST, 3 UNCERTAIN (followed, pose not trusted)"),
    ("reason", 32, 8, False, 1, 0, 0, 255,  "",
     "Lost reason bits: 1 low score, 2 low PSR, 4 flat frame, 8 out of field, 16 bad frame, 32 commanded (a REACQUIRE, or sempose's own re-search when look_alike is 1), 64 unsettled (the walk hit its angle step bound, or its place is on the ROI's edge: the peak may lie outside), "
     "128 unexplained (the pattern does not explain the window up to noise)"),
    ("seq", 40, 8, False, 1, 0, 0, 255, "", "Pose sequence counter (low 8 bits), same in POSE_XY"),
    ("age", 48, 12, False, 8, 0, 0, 32760, "us", "Beam on the target (the time the pose is valid for) to send, in 8 us steps (rounded, saturating)"),
    ("angle_order", 60, 3, False, 1, 0, 0, 7, "", ANGLE_ORDER),
    ("look_alike", 63, 1, False, 1, 0, 0, 1, "",
     "1: a target with the same pattern is on this pose's place (state UNCERTAIN while both are there), or this pose comes from the search sempose started because of it (reason 32 on such a frame is sempose's own, not a controller REACQUIRE)"),
]
POSE_FD = [
    ("x", 0, 32, True, 1, 0, -2147483648, 2147483647, "nm", "Pattern centre x (saturating)"),
    ("y", 32, 32, True, 1, 0, -2147483648, 2147483647, "nm", "Pattern centre y (saturating)"),
    ("phi", 64, 32, True, 0.001, 0, -180, 180, "deg", "Orientation"),
    ("score", 96, 16, True, 0.0001, 0, -1, 1, "", "ZNCC peak score"),
    ("state", 112, 8, False, 1, 0, 0, 3, "", "0 TRACKING, 1 ACQUIRING, 2 LOST, 3 UNCERTAIN (followed, pose not trusted)"),
    ("reason", 120, 8, False, 1, 0, 0, 255, "", "Lost reason bits (see POSE_ATTR)"),
    ("seq", 128, 32, False, 1, 0, 0, 4294967295, "", "Pose sequence counter"),
    ("age", 160, 32, False, 1, 0, 0, 4294967295, "us", "Beam on the target (the time the pose is valid for) to send"),
    ("psr", 192, 16, False, 0.01, 0, 0, 655.35, "", "Peak-to-sidelobe ratio"),
    ("pattern_set", 208, 8, False, 1, 0, 0, 255, "", "Active pattern set / magnification step"),
    ("target", 216, 8, False, 1, 0, 0, 3, "", "Target index"),
    ("dwell", 224, 32, False, 1, 0, 0, 4294967295, "ns", "Pixel dwell of the frame"),
    ("frame_seq", 256, 32, False, 1, 0, 0, 4294967295, "", "Scan-source frame counter (low 32 bits)"),
    ("scale", 288, 32, False, 0.001, 0, 0, 4294967.295, "nm/px", "nm per pixel of the active pattern set"),
    ("target_scale", 320, 16, False, 0.0001, 0, 0, 6.5535, "", "The target's size on screen over its pattern's (tracked scale)"),
    ("sigma_x", 336, 32, False, 0.001, 0, 0, 4294967.295, "nm", "1 sigma of x, calibrated (0 = not measured)"),
    ("sigma_y", 368, 32, False, 0.001, 0, 0, 4294967.295, "nm", "1 sigma of y, calibrated (0 = not measured)"),
    ("sigma_phi", 400, 32, False, 0.000001, 0, 0, 4294.967295, "deg", "1 sigma of phi, calibrated (0 = not measured)"),
    ("sigma_scale", 432, 32, False, 0.000001, 0, 0, 4294.967295, "", "1 sigma of target_scale (0 = not measured)"),
    ("look_alike", 464, 1, False, 1, 0, 0, 1, "", "See POSE_ATTR"),
    ("angle_order", 472, 8, False, 1, 0, 0, 7, "", ANGLE_ORDER),
]
POSE_UNC = [
    ("sigma_x", 0, 12, False, 0.1, 0, 0, 409.5, "nm", "1 sigma of x, calibrated (0 = not measured, saturating)"),
    ("sigma_y", 12, 12, False, 0.1, 0, 0, 409.5, "nm", "1 sigma of y, calibrated (0 = not measured, saturating)"),
    ("sigma_phi", 24, 11, False, 0.001, 0, 0, 2.047, "deg", "1 sigma of phi, calibrated (0 = not measured, saturating)"),
    ("target_scale", 35, 14, False, 0.0001, 0.5, 0.5, 2.1383, "", "The target's size on screen over its pattern's (saturating)"),
    ("sigma_scale", 49, 7, False, 0.0005, 0, 0, 0.0635, "", "1 sigma of target_scale (0 = not measured, saturating)"),
    ("seq", 56, 8, False, 1, 0, 0, 255, "", "Pose sequence counter (low 8 bits), same in POSE_XY"),
]
HEARTBEAT = [
    ("state", 0, 2, False, 1, 0, 0, 3, "", "0 TRACKING, 1 ACQUIRING, 2 LOST, 3 UNCERTAIN (worst over targets: LOST, ACQUIRING, UNCERTAIN, TRACKING)"),
    ("running", 2, 1, False, 1, 0, 0, 1, "", "0 after a STOP command"),
    ("bus_state", 3, 2, False, 1, 0, 0, 2, "", "0 error active, 1 error passive, 2 bus off"),
    ("fd", 5, 1, False, 1, 0, 0, 1, "", "1 when poses go out as CAN FD POSE_FD frames"),
    ("output_fault", 6, 1, False, 1, 0, 0, 1, "", "1 after a file output (CSV, candump log) failed to write"),
    ("stalled", 7, 1, False, 1, 0, 0, 1, "", "1 while the scan source or an RT stage makes no progress (state then LOST; the systemd watchdog is starved)"),
    ("pattern_set", 8, 4, False, 1, 0, 0, 15, "", "Active pattern set / magnification step"),
    ("bad_commands", 12, 4, False, 1, 0, 0, 15, "", "Commands that took no effect (malformed, ring full, naming a missing set or target), mod 16"),
    ("counter", 16, 8, False, 1, 0, 0, 255, "", "+1 per heartbeat"),
    ("last_command_seq", 24, 8, False, 1, 0, 0, 255, "", "seq of the last command that took effect"),
    ("dwell", 32, 16, False, 1, 0, 0, 65535, "ns", "Pixel dwell (saturating)"),
    ("dropped_frames", 48, 8, False, 1, 0, 0, 255, "", "Frames dropped by the pipeline, mod 256"),
    ("overruns", 56, 4, False, 1, 0, 0, 15, "", "Cycle overruns, mod 16"),
    ("tx_dropped", 60, 4, False, 1, 0, 0, 15, "", "CAN frames not sent (queue full / bus off), mod 16"),
]
COMMAND = [
    ("opcode", 0, 8, False, 1, 0, 1, 4, "", "1 SELECT_PATTERN_SET, 2 START, 3 STOP, 4 REACQUIRE"),
    ("seq", 8, 8, False, 1, 0, 0, 255, "", "Controller's command counter, echoed in HEARTBEAT.last_command_seq"),
    ("arg", 16, 8, False, 1, 0, 0, 255, "", "SELECT: pattern set 0..15; REACQUIRE: target 0..3 or 255 = all; else 0"),
    ("reserved", 24, 8, False, 1, 0, 0, 0, "", "Must be 0"),
    ("scale", 32, 32, False, 0.001, 0, 0, 100000, "nm/px", "SELECT only: nm per pixel of the set (0 = keep configured); else 0"),
]
VALUES = {
    "state": '0 "TRACKING" 1 "ACQUIRING" 2 "LOST" 3 "UNCERTAIN"',
    "bus_state": '0 "ERROR_ACTIVE" 1 "ERROR_PASSIVE" 2 "BUS_OFF"',
    "opcode": '1 "SELECT_PATTERN_SET" 2 "START" 3 "STOP" 4 "REACQUIRE"',
}


def fmt(v):
    return ("%.10g" % v) if isinstance(v, float) else str(v)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--base", type=lambda s: int(s, 0), default=0x100)
    ap.add_argument("--command-id", type=lambda s: int(s, 0), default=None)
    a = ap.parse_args()
    cmd_id = a.command_id if a.command_id is not None else a.base + 0x50
    msgs = []  # (id, name, dlc, sender, signals, comment, fd, cycle_ms)
    for t in range(TARGETS):
        b = a.base + BLOCK * t
        msgs.append((b + 0, "POSE_XY_T%d" % t, 8, "SEMPOSE", POSE_XY, "Pose of target %d: position" % t, False, 0))
        msgs.append((b + 1, "POSE_ATTR_T%d" % t, 8, "SEMPOSE", POSE_ATTR, "Pose of target %d: orientation (and its rotational order), score, state, age" % t, False, 0))
        msgs.append((b + 2, "POSE_FD_T%d" % t, 64, "SEMPOSE", POSE_FD, "Pose of target %d as one CAN FD frame (instead of XY+ATTR+UNC)" % t, True, 0))
        msgs.append((b + 3, "POSE_UNC_T%d" % t, 8, "SEMPOSE", POSE_UNC, "Pose of target %d: 1 sigma of x, y, phi, scale; the target's scale" % t, False, 0))
    msgs.append((a.base + 0x40, "HEARTBEAT", 8, "SEMPOSE", HEARTBEAT, "Status at can.heartbeat_hz", False, 100))
    msgs.append((cmd_id, "COMMAND", 8, "CONTROLLER", COMMAND, "Command from the controller; invalid ones are counted and ignored", False, 0))
    out = []
    w = out.append
    w('VERSION "sempose-%d"\n\n' % WIRE_VERSION)
    w("NS_ :\n\tCM_\n\tBA_DEF_\n\tBA_\n\tVAL_\n\tBA_DEF_DEF_\n\nBS_:\n\nBU_: SEMPOSE CONTROLLER\n\n")
    for mid, name, dlc, sender, sigs, _, _, _ in msgs:
        w("BO_ %d %s: %d %s\n" % (mid, name, dlc, sender))
        rx = "CONTROLLER" if sender == "SEMPOSE" else "SEMPOSE"
        for (s, start, ln, signed, f, o, lo, hi, unit, _) in sigs:
            w(' SG_ %s : %d|%d@1%s (%s,%s) [%s|%s] "%s" %s\n' % (s, start, ln, "-" if signed else "+", fmt(f), fmt(o), fmt(lo), fmt(hi), unit, rx))
        w("\n")
    w('BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;\n')
    w('BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","J1939PG","reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved","StandardCAN_FD","ExtendedCAN_FD";\n')
    w('BA_DEF_DEF_ "GenMsgCycleTime" 0;\nBA_DEF_DEF_ "VFrameFormat" "StandardCAN";\n')
    for mid, name, _, _, sigs, comment, fd, cyc in msgs:
        if fd:
            w('BA_ "VFrameFormat" BO_ %d 14;\n' % mid)
        if cyc:
            w('BA_ "GenMsgCycleTime" BO_ %d %d;\n' % (mid, cyc))
    w("\n")
    for mid, name, _, _, sigs, comment, _, _ in msgs:
        w('CM_ BO_ %d "%s";\n' % (mid, comment))
        for s in sigs:
            w('CM_ SG_ %d %s "%s";\n' % (mid, s[0], s[9]))
    w("\n")
    for mid, name, _, _, sigs, _, _, _ in msgs:
        for s in sigs:
            if s[0] in VALUES:
                w("VAL_ %d %s %s ;\n" % (mid, s[0], VALUES[s[0]]))
    print("".join(out), end="")


if __name__ == "__main__":
    main()
