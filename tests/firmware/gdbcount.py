#!/usr/bin/env python3
"""Counts the instructions of controller steps on the emulated Cortex-M4F by single-stepping.

The second, independent count behind `tests/firmware/measure`; the first is the firmware's
own, from SysTick under QEMU -icount. This one never reads a clock: it starts the unmodified
firmware ELF under qemu-system-arm with the gdb stub on a Unix socket, speaks the gdb remote
serial protocol itself (no gdb needed) and counts single steps.

For step k of a case it
  1. breaks at `companion_case_start`, which the firmware calls just before each case with
     the case's name (read from memory: pointer in r0, length in r1);
  2. writes k into the firmware's `COMPANION_STOP_AT` and breaks at `companion_step_mark`,
     which the firmware's probe calls before step k of the case, outside the step's SysTick
     readings (a breakpoint there, not at each of the k steps before: one stop, not k);
  3. sets a read watchpoint on SysTick's current-value register (0xE000E018) and
     continues: the stub stops *at* the load (before it), the reading that starts step k;
  4. single-steps from that reading, with the watchpoint set, until the stub stops at the
     next load from SysTick (the reading that ends step k), counting; on the way it notes
     the entry of the case's step function, `scenario::controller_step::<T, Platform>`
     (never inlined; one instance per scalar type and platform) or `scenario::spatial_step`
     for the spatial cases (`ur5-…`), and the return to the caller (program counter at the
     return address, stack pointer restored).
It reports the instructions strictly between the two readings (the firmware's definition
of a step's count) and, of those, the instructions of the step function from its first to
its return instruction. With --trace DIR it also writes, per counted step, the program
counter, stack pointer and link register before each instruction to DIR/CASE-STEP.trace
(one `pc sp lr` line each, hex), which `profile.py` attributes to functions.

Usage: gdbcount.py [--trace DIR] ELF CASE:STEP[,STEP...] [CASE:STEP...]
  e.g. gdbcount.py target/thumbv7em-none-eabihf/release/companion-firmware uni-1a-f32:0,1,2 uni-1a-f64:1
Prints one line per step, in the order they run:
  G <case> <step> <instructions between the readings> <instructions of the step function>
Exit status 0 on success, 2 on any failure (with a message on stderr). About 6 000 single
steps per second.
"""

import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
# Platform part of a case name -> the platform type in the symbol of controller_step.
PLATFORMS = {"uni": "Unicycle", "car": "CarLike", "omni": "Omnidirectional"}
# SysTick's current value register (SYST_CVR), read at both ends of every counted step.
SYST_CVR = 0xE000_E018
# Most single steps one count may take (an f64 step is ~10^5; this bounds a runaway).
MAX_STEPS = 5_000_000
# Seconds allowed for the whole run.
TIME_LIMIT = 300


class Failure(Exception):
    """A reason the count could not be made."""


def parse_case(case):
    """(step function, platform type, scalar) of a case name: `uni-2c-f32[-sampled|-limits]` is the
    planar law's `controller_step`, `ur5-uni-1a-f32` the spatial law's `spatial_step`."""
    parts = case.split("-")
    function = "controller_step"
    if parts and parts[0] == "ur5":
        function, parts = "spatial_step", parts[1:]
    if parts[3:] in (["sampled"], ["limits"]):
        parts = parts[:3]
    if (
        len(parts) != 3
        or parts[0] not in PLATFORMS
        or not re.fullmatch(r"[12][a-d]", parts[1])
        or parts[2] not in ("f32", "f64")
    ):
        raise Failure(f"unknown case {case!r}: expected [ur5-](uni|car|omni)-(1|2)(a|b|c|d)-(f32|f64)[-sampled|-limits]")
    return function, PLATFORMS[parts[0]], parts[2]


def symbols(elf):
    """`nm -C` of the ELF."""
    nm = shutil.which("nm") or shutil.which("llvm-nm")
    if nm is None:
        raise Failure("neither nm (binutils) nor llvm-nm is on the PATH")
    return subprocess.run([nm, "-C", elf], capture_output=True, text=True, check=True).stdout


def exported(elf, name):
    """Address of the firmware's unmangled symbol `name` (src/main.rs)."""
    found = [int(line.split()[0], 16) for line in symbols(elf).splitlines() if line.endswith(" " + name)]
    if len(found) != 1:
        raise Failure(f"{len(found)} symbols {name} in {elf} (expected one: see src/main.rs)")
    return found[0] & ~1


def step_function_address(elf, case):
    """Entry address of the step function's instance for `case` (e.g. uni-a-f32)."""
    function, plat, ty = parse_case(case)
    out = symbols(elf)
    pattern = re.compile(rf"^([0-9a-f]+) [tT] .*scenario::{function}::<{ty}, [\w:]*\b{plat}\b")
    found = [int(m.group(1), 16) for line in out.splitlines() if (m := pattern.match(line))]
    if len(found) != 1:
        raise Failure(
            f"{len(found)} symbols match {function}::<{ty}, …{plat}…> in {elf} "
            "(expected one: is it still #[inline(never)] in src/scenario.rs?)"
        )
    return found[0] & ~1  # clear the Thumb bit


class Remote:
    """A minimal client of the gdb remote serial protocol (no-ack mode after the start)."""

    def __init__(self, path, qemu, deadline):
        self.deadline = deadline
        self.buf = b""
        self.ack = True
        give_up = time.monotonic() + 30
        while True:
            self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                self.sock.connect(path)
                break
            except OSError:
                self.sock.close()
                if qemu.poll() is not None:
                    err = qemu.stderr.read().decode(errors="replace").strip()
                    raise Failure(f"QEMU exited with {qemu.returncode} before its gdb stub opened: {err}") from None
                if time.monotonic() > give_up:
                    raise Failure("QEMU's gdb stub did not open its socket within 30 s") from None
                time.sleep(0.05)
        self.sock.settimeout(30)
        if self.command("QStartNoAckMode") == "OK":
            self.ack = False

    def command(self, payload):
        """Sends one packet and returns the payload of the reply."""
        data = payload.encode()
        self.sock.sendall(b"$%s#%02x" % (data, sum(data) & 0xFF))
        while True:
            start = self.buf.find(b"$")
            end = self.buf.find(b"#", start + 1) if start >= 0 else -1
            if start >= 0 and end >= 0 and len(self.buf) >= end + 3:
                body, checksum = self.buf[start + 1 : end], self.buf[end + 1 : end + 3]
                self.buf = self.buf[end + 3 :]
                if self.ack:
                    self.sock.sendall(b"+")
                if int(checksum, 16) != sum(body) & 0xFF:
                    raise Failure(f"bad checksum from the gdb stub: {body!r}")
                return body.decode()
            try:
                chunk = self.sock.recv(65536)
            except socket.timeout:
                raise Failure(f"QEMU's gdb stub stopped answering ({self.sock.gettimeout():.0f} s)") from None
            if not chunk:
                raise Failure("QEMU closed the gdb connection (did the firmware exit early?)")
            self.buf += chunk

    def registers(self):
        """r0..r15 (13 = SP, 14 = LR, 15 = PC), from one `g` packet (QEMU answers `p`
        only to clients that have read its XML target description)."""
        reply = self.command("g")
        if len(reply) < 16 * 8:
            raise Failure(f"unexpected reply to reading the registers: {reply!r}")
        return [int.from_bytes(bytes.fromhex(reply[8 * i : 8 * i + 8]), "little") for i in range(16)]

    def pc(self):
        return self.registers()[15]

    def write_word(self, addr, value):
        """Writes a 32-bit little-endian word at `addr`."""
        reply = self.command(f"M{addr:x},4:{value.to_bytes(4, 'little').hex()}")
        if reply != "OK":
            raise Failure(f"could not write at {addr:#x}: {reply!r}")

    def memory(self, addr, length):
        """`length` bytes at `addr`."""
        reply = self.command(f"m{addr:x},{length:x}")
        try:
            data = bytes.fromhex(reply)
        except ValueError:
            data = b""
        if len(data) != length:
            raise Failure(f"could not read {length} bytes at {addr:#x}: {reply!r}")
        return data

    def resume(self, packet, what):
        """Sends `s` or `c`; returns the stop reply (a signal stop, else a Failure). A
        continue may run for long (to the spatial cases, past every f64 case: ~30 s of
        emulation, more on a loaded machine), so it may take until the deadline."""
        if packet == "c":
            self.sock.settimeout(max(30.0, self.deadline - time.monotonic()))
        try:
            reply = self.command(packet)
        finally:
            self.sock.settimeout(30)
        if not reply.startswith(("T05", "S05")):
            raise Failure(f"{what}: the target stopped with {reply!r} (exited or faulted?)")
        if time.monotonic() > self.deadline:
            raise Failure(f"took longer than {TIME_LIMIT} s")
        return reply

    def step(self):
        """One instruction (also off a breakpoint at the current address; not off a
        watchpoint, which stops before its load: remove the watchpoint first)."""
        self.resume("s", "single step")

    def point(self, kind, addr, on, length=2):
        """Sets or removes a breakpoint (kind 0) or read watchpoint (kind 3)."""
        reply = self.command(f"{'Z' if on else 'z'}{kind},{addr:x},{length}")
        if reply != "OK":
            raise Failure(f"the gdb stub refused {'Z' if on else 'z'}{kind} at {addr:#x}: {reply!r}")

    def next_reading(self):
        """Continues to the next load from SYST_CVR; returns its address (not yet executed)."""
        self.point(3, SYST_CVR, True, 4)
        reply = self.resume("c", "continue to a SysTick reading")
        self.point(3, SYST_CVR, False, 4)
        if "watch:" not in reply:
            raise Failure(f"expected a SysTick reading, stopped with {reply!r} at {self.pc():#x}")
        return self.pc()


def count_bracket(remote, entry, trace=None):
    """At the reading that starts a step (stopped at it, the watchpoint removed):
    single-steps with the watchpoint set until the stub stops at the next reading, the one
    that ends the step (not executed); returns (instructions strictly between the
    readings, instructions of the call of `entry`). `trace`: a file that receives `pc sp
    lr` before each instruction counted."""
    start = remote.pc()
    remote.step()  # the starting reading itself
    steps, called, returned = 1, None, None
    remote.point(3, SYST_CVR, True, 4)
    while True:
        regs = remote.registers()
        if regs[15] == entry and called is None:
            called, ret, sp = steps, regs[14] & ~1, regs[13]
        elif called is not None and returned is None and regs[15] == ret and regs[13] == sp:
            returned = steps
        reply = remote.resume("s", "single step")
        if "watch:" in reply:
            break
        if trace is not None:
            trace.write(f"{regs[15]:x} {regs[13]:x} {regs[14]:x}\n")
        steps += 1
        if steps >= MAX_STEPS:
            raise Failure(f"no SysTick reading within {MAX_STEPS} instructions of {start:#x}")
    remote.point(3, SYST_CVR, False, 4)
    if called is None or returned is None:
        raise Failure(f"the readings from {start:#x} to {remote.pc():#x} do not bracket a call of {entry:#x}")
    return steps - 1, returned - called


def count(elf, wanted, trace_dir=None):
    """Counts the steps in `wanted` ({case: [step, ...]}) and prints a `G` line for each, in
    the order they run."""
    marker, mark = exported(elf, "companion_case_start"), exported(elf, "companion_step_mark")
    stop_at = exported(elf, "COMPANION_STOP_AT")
    entries = {case: step_function_address(elf, case) for case in wanted}
    with tempfile.TemporaryDirectory() as tmp:
        sock = os.path.join(tmp, "gdb.sock")
        qemu = subprocess.Popen(
            ["qemu-system-arm", "-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic"]
            # -icount only so that the firmware passes its own calibration checks and runs as
            # in `measure`; the count here never reads a clock.
            + ["-semihosting-config", "enable=on,target=native", "-icount", "shift=7", "-kernel", elf]
            + ["-chardev", f"socket,id=gdb,path={sock},server=on,wait=on"]
            + ["-gdb", "chardev:gdb", "-S"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        try:
            remote = Remote(sock, qemu, time.monotonic() + TIME_LIMIT)
            remote.point(0, marker, True)
            left = dict(wanted)
            while left:
                remote.resume("c", "continue to the next case")
                regs = remote.registers()
                if regs[15] != marker:
                    raise Failure(f"stopped at {regs[15]:#x}, not at companion_case_start")
                name = remote.memory(regs[0], regs[1]).decode(errors="replace") if 0 < regs[1] < 64 else ""
                remote.step()  # off the breakpoint
                if name not in left:
                    continue
                entry, steps = entries[name], left.pop(name)
                remote.point(0, mark, True)
                for k in steps:
                    # The firmware calls companion_step_mark before step k (outside its
                    # readings); the next reading after it starts step k.
                    remote.write_word(stop_at, k)
                    remote.resume("c", f"continue to {name}'s step {k}")
                    regs = remote.registers()
                    if regs[15] != mark or regs[0] != k:
                        raise Failure(f"{name}: stopped at {regs[15]:#x} (r0 = {regs[0]}), not at the mark of step {k}")
                    remote.step()  # off the breakpoint
                    remote.next_reading()
                    trace = open(os.path.join(trace_dir, f"{name}-{k}.trace"), "w") if trace_dir else None
                    try:
                        between, call = count_bracket(remote, entry, trace)
                    finally:
                        if trace is not None:
                            trace.close()
                    print(f"G {name} {k} {between} {call}", flush=True)
                remote.point(0, mark, False)
                remote.write_word(stop_at, 0xFFFF_FFFF)
            if left:
                raise Failure(f"no case named {', '.join(left)} ran")
        finally:
            qemu.kill()
            qemu.communicate()


def main(argv):
    trace_dir = None
    if len(argv) > 2 and argv[1] == "--trace":
        trace_dir, argv = argv[2], argv[:1] + argv[3:]
        os.makedirs(trace_dir, exist_ok=True)
    if len(argv) < 3:
        sys.stderr.write(__doc__)
        return 2
    if shutil.which("qemu-system-arm") is None:
        sys.stderr.write("gdbcount: qemu-system-arm is not installed (run scripts/setup)\n")
        return 2
    wanted = {}
    try:
        if not os.path.isfile(argv[1]):
            raise Failure(f"no firmware ELF at {argv[1]} (build it first: tests/firmware/measure does)")
        for arg in argv[2:]:
            case, _, steps = arg.partition(":")
            try:
                wanted[case] = sorted({int(s) for s in steps.split(",")})
            except ValueError:
                raise Failure(f"bad argument {arg!r}: expected CASE:STEP[,STEP...]") from None
        count(argv[1], wanted, trace_dir)
    except (Failure, subprocess.CalledProcessError, OSError) as e:
        sys.stderr.write(f"gdbcount: {e}\n")
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
