"""SOEM (pysoem) as the MainDevice of the emulated segment: finds the SubDevices
with their identities, maps the process data, reaches OP with DC SYNC0 on the
drives, enables drive 0 by its controlword and moves it, writes the I/O terminal's
outputs and reads its inputs. Prints what it saw; exits non-zero on a failure.

usage: soem_master.py IFACE EXPECTED_INPUT_BYTE
"""
import struct
import sys
import time

import pysoem

CYCLE_S = 0.001
FAILED = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what, flush=True)
    if not ok:
        FAILED.append(what)


def cycle(m):
    m.send_processdata()
    wkc = m.receive_processdata(2000)
    time.sleep(CYCLE_S)
    return wkc


def main():
    iface, expected_input = sys.argv[1], int(sys.argv[2], 0)
    m = pysoem.Master()
    m.open(iface)
    n = m.config_init()
    check(n == 4, f"config_init found {n} SubDevices")
    for i, s in enumerate(m.slaves):
        print(f"subdevice {i}: {s.name!r} vendor {s.man:#010x} product {s.id:#010x} revision {s.rev:#010x}")
    drives = [s for s in m.slaves if s.id == 0x402]
    check(len(drives) == 3, "three drives by product code")
    for s in drives:
        # CSP, and the device's own name by a normal (non-expedited) SDO upload
        s.sdo_write(0x6060, 0, struct.pack("<b", 8))
        check(s.sdo_read(0x6060, 0)[0] == 8, "modes of operation 8 written by SDO")
        name = s.sdo_read(0x1008, 0).decode()
        check(name == "softnc emulated CiA 402 drive", f"0x1008 by normal upload: {name!r}")
        ident = struct.unpack("<I", s.sdo_read(0x1018, 2))[0]
        check(ident == 0x402, "0x1018:02 product code")
        try:
            s.sdo_read(0x2345, 0)
            check(False, "reading a missing object aborts")
        except pysoem.SdoError as e:
            check(e.abort_code == 0x06020000, f"a missing object aborts with {e.abort_code:#010x}")
    size = m.config_map()
    check(size == 3 * (6 + 6) + 2, f"process image {size} bytes")
    check(m.config_dc(), "DC found")
    for s in drives:
        s.dc_sync(True, int(CYCLE_S * 1e9))
    check(m.state_check(pysoem.SAFEOP_STATE, 500000) == pysoem.SAFEOP_STATE, "all in SAFE-OP")
    m.state = pysoem.OP_STATE
    m.write_state()
    for _ in range(200):
        cycle(m)
        if m.state_check(pysoem.OP_STATE, 1000) == pysoem.OP_STATE:
            break
    check(m.read_state() == pysoem.OP_STATE, "all in OP")
    expected_wkc = m.expected_wkc
    wkc = cycle(m)
    check(wkc == expected_wkc, f"working counter {wkc} of {expected_wkc}")

    d = drives[0]
    status, pos = struct.unpack("<Hi", d.input[:6])
    start = pos
    for cw in (0x06, 0x07, 0x0F):
        d.output = struct.pack("<Hi", cw, start)
        for _ in range(3):
            cycle(m)
    status, pos = struct.unpack("<Hi", d.input[:6])
    check(status & 0x6F == 0x27, f"drive 0 operation enabled (statusword {status:#06x})")
    step = 100  # counts per cycle
    for k in range(1, 301):
        d.output = struct.pack("<Hi", 0x0F, start + step * min(k, 200))
        cycle(m)
    status, pos = struct.unpack("<Hi", d.input[:6])
    moved = pos - start
    check(abs(moved - 200 * step) <= 20, f"drive 0 moved {moved} counts of {200 * step}")

    io = [s for s in m.slaves if s.id == 0x80808][0]
    io.output = bytes([0xA5])
    for _ in range(3):
        cycle(m)
    check(io.input[0] == expected_input, f"terminal inputs {io.input[0]:#04x}")

    # the segment stays in OP: the test reads the terminal's outputs back
    m.close()
    print("SOEM done:", "failed: " + ", ".join(FAILED) if FAILED else "all checks passed", flush=True)
    sys.exit(1 if FAILED else 0)


main()
