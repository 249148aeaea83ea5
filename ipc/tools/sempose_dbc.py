#!/usr/bin/python3
"""A small DBC reader and decoder for sempose frames (Debian 12 has no python3-cantools).

Library use (tests/system/check_results.py can import it):
    db = Dbc.load("ipc/sempose.dbc")
    name, signals = db.decode(can_id, data)          # signals: {name: physical value}

Command line: decode a candump -l log (read with python-can's CanutilsLogReader):
    /usr/bin/python3 ipc/tools/sempose_dbc.py ipc/sempose.dbc candump.log [--json]
prints one line per frame: `<timestamp> <id hex> <FD|CC> <message> sig=value ...`
(unknown ids print as `? len=N`). Handles Intel (@1) signals, which is all sempose uses.
"""
import json
import re
import sys

_BO = re.compile(r"^BO_\s+(\d+)\s+(\w+)\s*:\s*(\d+)\s+(\w+)")
_SG = re.compile(r"^\s*SG_\s+(\w+)\s*:\s*(\d+)\|(\d+)@([01])([+-])\s*\(([^,]+),([^)]+)\)\s*\[([^|]+)\|([^\]]+)\]\s*\"([^\"]*)\"")
_VAL = re.compile(r"^VAL_\s+(\d+)\s+(\w+)\s+(.*);")


class Signal:
    def __init__(self, name, start, length, little, signed, factor, offset, lo, hi, unit):
        self.name, self.start, self.length = name, start, length
        self.little, self.signed = little, signed
        self.factor, self.offset, self.min, self.max, self.unit = factor, offset, lo, hi, unit
        self.values = {}

    def raw(self, data):
        if not self.little:
            raise ValueError("Motorola (@0) signals are not used by sempose")
        v = int.from_bytes(bytes(data), "little") >> self.start
        v &= (1 << self.length) - 1
        if self.signed and v & (1 << (self.length - 1)):
            v -= 1 << self.length
        return v

    def decode(self, data):
        return self.raw(data) * self.factor + self.offset


class Message:
    def __init__(self, can_id, name, dlc, sender):
        self.id, self.name, self.dlc, self.sender = can_id, name, dlc, sender
        self.signals = []


class Dbc:
    def __init__(self):
        self.messages = {}

    @staticmethod
    def load(path):
        db = Dbc()
        cur = None
        with open(path) as f:
            for line in f:
                m = _BO.match(line)
                if m:
                    cur = Message(int(m.group(1)), m.group(2), int(m.group(3)), m.group(4))
                    db.messages[cur.id] = cur
                    continue
                m = _SG.match(line)
                if m and cur is not None:
                    num = lambda s: float(s) if any(c in s for c in ".eE") else int(s)
                    cur.signals.append(Signal(m.group(1), int(m.group(2)), int(m.group(3)), m.group(4) == "1",
                                              m.group(5) == "-", num(m.group(6)), num(m.group(7)),
                                              num(m.group(8)), num(m.group(9)), m.group(10)))
                    continue
                if not line.strip():
                    cur = None
                m = _VAL.match(line)
                if m:
                    msg = db.messages.get(int(m.group(1)))
                    pairs = re.findall(r'(\d+)\s+"([^"]*)"', m.group(3))
                    for s in (msg.signals if msg else []):
                        if s.name == m.group(2):
                            s.values = {int(k): v for k, v in pairs}
        return db

    def decode(self, can_id, data):
        msg = self.messages.get(can_id)
        if msg is None or len(data) != msg.dlc:
            return None, {}
        return msg.name, {s.name: s.decode(data) for s in msg.signals}


def main(argv):
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    import can  # python3-can (Debian)
    db = Dbc.load(argv[1])
    as_json = "--json" in argv
    for msg in can.CanutilsLogReader(argv[2]):
        if msg.is_error_frame:
            continue
        name, sigs = db.decode(msg.arbitration_id, msg.data)
        if as_json:
            print(json.dumps({"t": msg.timestamp, "id": msg.arbitration_id, "fd": msg.is_fd,
                              "channel": msg.channel, "name": name, "signals": sigs}))
        elif name is None:
            print("%.6f %03X %s ? len=%d" % (msg.timestamp, msg.arbitration_id, "FD" if msg.is_fd else "CC", len(msg.data)))
        else:
            print("%.6f %03X %s %s %s" % (msg.timestamp, msg.arbitration_id, "FD" if msg.is_fd else "CC", name,
                                          " ".join("%s=%.10g" % kv for kv in sigs.items())))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
