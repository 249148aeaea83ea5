#!/usr/bin/python3
"""Small self-contained DBC reader/encoder for the sempose system test.

Supports BO_ / SG_ (Intel @1 and Motorola @0 byte order, signed '-' / unsigned '+',
factor/offset, min/max, unit, simple multiplexing M / mN), VAL_ tables and CM_ comments.
Usage as a tool:
  dbc.py show FILE                       list messages and signals
  dbc.py encode FILE MESSAGE sig=val ... print "<ID>#<HEX>" (cansend syntax)
"""
import re
import sys
from dataclasses import dataclass, field


@dataclass
class Signal:
    name: str
    start: int
    length: int
    little_endian: bool
    signed: bool
    factor: float = 1.0
    offset: float = 0.0
    minimum: float = 0.0
    maximum: float = 0.0
    unit: str = ""
    mux: str = ""            # "M" for the multiplexer, "m<N>" for multiplexed signals
    choices: dict = field(default_factory=dict)   # raw value -> name (VAL_)
    comment: str = ""

    def _bit_positions(self, nbytes):
        """Yield (byte, bit) pairs from the LSB of the signal to its MSB."""
        if self.little_endian:
            for i in range(self.length):
                b = self.start + i
                yield b // 8, b % 8
        else:
            # Motorola: start is the MSB in sawtooth numbering; walk towards the LSB.
            pos = []
            b = self.start
            for _ in range(self.length):
                pos.append((b // 8, b % 8))
                if b % 8 == 0:
                    b += 15
                else:
                    b -= 1
            yield from reversed(pos)

    def raw(self, data: bytes) -> int:
        v = 0
        for i, (byte, bit) in enumerate(self._bit_positions(len(data))):
            if byte >= len(data):
                raise ValueError(f"signal {self.name} beyond frame length {len(data)}")
            v |= ((data[byte] >> bit) & 1) << i
        if self.signed and v & (1 << (self.length - 1)):
            v -= 1 << self.length
        return v

    def decode(self, data: bytes) -> float:
        return self.raw(data) * self.factor + self.offset

    def raw_from_phys(self, value: float) -> int:
        r = round((value - self.offset) / self.factor)
        lo, hi = (-(1 << (self.length - 1)), (1 << (self.length - 1)) - 1) if self.signed \
            else (0, (1 << self.length) - 1)
        if not lo <= r <= hi:
            raise ValueError(f"{self.name}={value} -> raw {r} out of [{lo},{hi}]")
        return r

    def insert(self, data: bytearray, raw: int):
        raw &= (1 << self.length) - 1
        for i, (byte, bit) in enumerate(self._bit_positions(len(data))):
            if (raw >> i) & 1:
                data[byte] |= 1 << bit
            else:
                data[byte] &= ~(1 << bit) & 0xFF

    def choice_value(self, pattern: str):
        """Raw value of the VAL_ entry whose name matches the regex, or None."""
        for raw, name in self.choices.items():
            if re.search(pattern, name, re.I):
                return raw
        return None


@dataclass
class Message:
    frame_id: int
    name: str
    length: int
    sender: str
    extended: bool
    signals: list = field(default_factory=list)
    comment: str = ""

    def signal(self, name):
        for s in self.signals:
            if s.name == name:
                return s
        return None

    def find_signal(self, pattern):
        """First signal whose name matches the regex (case-insensitive), or None."""
        for s in self.signals:
            if re.search(pattern, s.name, re.I):
                return s
        return None

    def decode(self, data: bytes) -> dict:
        mux_val = None
        for s in self.signals:
            if s.mux == "M":
                mux_val = s.raw(data)
        out = {}
        for s in self.signals:
            if s.mux.startswith("m") and mux_val is not None and int(s.mux[1:]) != mux_val:
                continue
            out[s.name] = s.decode(data)
        return out

    def encode(self, values: dict) -> bytes:
        data = bytearray(self.length)
        for name, v in values.items():
            s = self.signal(name)
            if s is None:
                raise KeyError(f"{self.name} has no signal {name}")
            s.insert(data, s.raw_from_phys(v))
        return bytes(data)


_BO = re.compile(r"^BO_\s+(\d+)\s+(\w+)\s*:\s*(\d+)\s+(\w+)")
_SG = re.compile(r"^SG_\s+(\w+)\s*(M|m\d+)?\s*:\s*(\d+)\|(\d+)@([01])([+-])\s*"
                 r"\(\s*([-+0-9.eE]+)\s*,\s*([-+0-9.eE]+)\s*\)\s*"
                 r"\[\s*([-+0-9.eE]+)\s*\|\s*([-+0-9.eE]+)\s*\]\s*\"([^\"]*)\"")
_VAL = re.compile(r"^VAL_\s+(\d+)\s+(\w+)\s+(.*);")
_CM = re.compile(r'^CM_\s+(BO_|SG_)\s+(\d+)\s+(?:(\w+)\s+)?"((?:[^"\\]|\\.)*)"\s*;', re.S)


class Database:
    def __init__(self, text: str):
        self.messages = []
        cur = None
        for lineno, line in enumerate(text.splitlines(), 1):
            s = line.strip()
            if s.startswith("BO_ "):
                m = _BO.match(s)
                if not m:
                    raise ValueError(f"line {lineno}: bad BO_: {s}")
                fid = int(m.group(1))
                ext = bool(fid & 0x80000000)
                cur = Message(fid & 0x1FFFFFFF, m.group(2), int(m.group(3)), m.group(4), ext)
                self.messages.append(cur)
            elif s.startswith("SG_ "):
                m = _SG.match(s)
                if not m or cur is None:
                    raise ValueError(f"line {lineno}: bad SG_: {s}")
                cur.signals.append(Signal(
                    name=m.group(1), mux=m.group(2) or "", start=int(m.group(3)),
                    length=int(m.group(4)), little_endian=m.group(5) == "1",
                    signed=m.group(6) == "-", factor=float(m.group(7)), offset=float(m.group(8)),
                    minimum=float(m.group(9)), maximum=float(m.group(10)), unit=m.group(11)))
            elif s.startswith("VAL_ "):
                m = _VAL.match(s)
                if m:
                    msg = self.by_id(int(m.group(1)) & 0x1FFFFFFF)
                    sig = msg.signal(m.group(2)) if msg else None
                    if sig:
                        for raw, name in re.findall(r"(-?\d+)\s+\"([^\"]*)\"", m.group(3)):
                            sig.choices[int(raw)] = name
            elif not s:
                cur = None
        for m in _CM.finditer(text):
            msg = self.by_id(int(m.group(2)) & 0x1FFFFFFF)
            if msg is None:
                continue
            if m.group(1) == "BO_":
                msg.comment = m.group(4)
            elif msg.signal(m.group(3) or ""):
                msg.signal(m.group(3)).comment = m.group(4)

    @classmethod
    def load(cls, path):
        with open(path, encoding="utf-8", errors="replace") as f:
            return cls(f.read())

    def by_id(self, frame_id):
        for m in self.messages:
            if m.frame_id == frame_id:
                return m
        return None

    def by_name(self, name):
        for m in self.messages:
            if m.name == name:
                return m
        return None

    def find(self, pattern, exclude=None):
        """Messages whose name matches the regex (case-insensitive)."""
        return [m for m in self.messages if re.search(pattern, m.name, re.I)
                and not (exclude and re.search(exclude, m.name, re.I))]


def cansend_string(msg: Message, data: bytes) -> str:
    fid = f"{msg.frame_id:08X}" if msg.extended else f"{msg.frame_id:03X}"
    return f"{fid}#{data.hex().upper()}"


def _main(argv):
    if len(argv) >= 2 and argv[0] == "show":
        db = Database.load(argv[1])
        for m in db.messages:
            print(f"0x{m.frame_id:X} {m.name} dlc={m.length}")
            for s in m.signals:
                print(f"   {s.name} {s.start}|{s.length}@{'1' if s.little_endian else '0'}"
                      f"{'-' if s.signed else '+'} ({s.factor},{s.offset}) [{s.minimum}|{s.maximum}]"
                      f" \"{s.unit}\" {s.mux} {s.choices or ''}")
        return 0
    if len(argv) >= 3 and argv[0] == "encode":
        db = Database.load(argv[1])
        msg = db.by_name(argv[2])
        vals = {k: float(v) for k, v in (a.split("=", 1) for a in argv[3:])}
        print(cansend_string(msg, msg.encode(vals)))
        return 0
    print(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
