#!/usr/bin/env python3
"""Counts the instructions of controller steps on the emulated Cortex-M4F by single-stepping.

The second, independent count behind `tests/firmware/measure`; the first is the firmware's
own, from SysTick under QEMU -icount. This one never reads a clock: it starts the unmodified
firmware ELF under qemu-system-arm with the gdb stub on a Unix socket, speaks the gdb remote
serial protocol itself (no gdb needed) and counts single steps.

For step k (k >= 1) of a case it
  1. breaks at the entry of `scenario::controller_step::<T, Platform>` (never inlined; one
     instance per scalar type and platform, whose calls in run (a) come first), or of
     `scenario::spatial_step` for the spatial cases (`ur5-…`), and skips to call k - 1;
  2. sets a read watchpoint on SysTick's current-value register (0xE000E018) and continues:
     the stub stops *at* each load from it, so the first stop is the reading that ends step
     k - 1 and the second the reading that starts step k;
  3. single-steps from that reading until the program counter reaches the ending reading's
     address again, counting; on the way it notes the entry of controller_step and the
     return to the caller (program counter at the return address, stack pointer restored).
It reports the instructions strictly between the two readings (the firmware's definition
of a step's count) and, of those, the instructions of controller_step from its first to its
return instruction. Step 0 cannot be bracketed this way (no step before it).

Usage: gdbcount.py ELF CASE:STEP[,STEP...] [CASE:STEP...]
  e.g. gdbcount.py target/thumbv7em-none-eabihf/release/companion-firmware uni-a-f32:1,2 uni-a-f64:1
Prints one line per step, in the order they run:
  G <case> <step> <instructions between the readings> <instructions of controller_step>
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


def steps_per_case():
    """Steps per case of the scenario (run (c) of a platform follows its run (a))."""
    src = (HERE / "src" / "scenario.rs").read_text()
    m = re.search(r"pub const STEPS: u32 = ([0-9_]+);", src)
    if not m:
        raise Failure("cannot find `pub const STEPS: u32 = …;` in src/scenario.rs")
    return int(m.group(1).replace("_", ""))


def parse_case(case):
    """(step function, platform type, run, scalar) of a case name: `uni-a-f32` is the planar
    law's `controller_step`, `ur5-uni-a-f32` the spatial law's `spatial_step`."""
    parts = case.split("-")
    function = "controller_step"
    if len(parts) == 4 and parts[0] == "ur5":
        function, parts = "spatial_step", parts[1:]
    if len(parts) != 3 or parts[0] not in PLATFORMS or parts[1] not in "ac" or parts[2] not in ("f32", "f64"):
        raise Failure(f"unknown case {case!r}: expected [ur5-](uni|car|omni)-(a|c)-(f32|f64)")
    return function, PLATFORMS[parts[0]], parts[1], parts[2]


def step_function_address(elf, case):
    """Entry address of the step function's instance for `case` (e.g. uni-a-f32)."""
    function, plat, _, ty = parse_case(case)
    nm = shutil.which("nm") or shutil.which("llvm-nm")
    if nm is None:
        raise Failure("neither nm (binutils) nor llvm-nm is on the PATH")
    out = subprocess.run([nm, "-C", elf], capture_output=True, text=True, check=True).stdout
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


def count_bracket(remote, entry, end):
    """At the reading that starts a step: single-steps to the address `end` of the reading
    that ends it; returns (instructions strictly between the readings, instructions of the
    call of `entry`)."""
    start = remote.pc()
    steps, called, returned = 0, None, None
    while True:
        remote.step()
        steps += 1
        regs = remote.registers()
        if regs[15] == entry and called is None:
            called, ret, sp = steps, regs[14] & ~1, regs[13]
        elif called is not None and returned is None and regs[15] == ret and regs[13] == sp:
            returned = steps
        if regs[15] == end:
            break
        if steps >= MAX_STEPS:
            raise Failure(f"no SysTick reading at {end:#x} within {MAX_STEPS} instructions of {start:#x}")
    if called is None or returned is None:
        raise Failure(f"the readings at {start:#x} and {end:#x} do not bracket a call of {entry:#x}")
    return steps - 1, returned - called


def count(elf, wanted):
    """Counts the steps in `wanted` ({case: [step, ...]}) and prints a `G` line for each, in
    the order they run."""
    per_case = steps_per_case()
    plan = {}  # entry address -> {call index of that instance: (case, step)}
    for case, steps in wanted.items():
        entry = step_function_address(elf, case)
        offset = 0 if parse_case(case)[2] == "a" else per_case
        for k in steps:
            if not 1 <= k < per_case:
                raise Failure(f"{case}: step {k} cannot be counted (steps 1 to {per_case - 1} can)")
            plan.setdefault(entry, {})[offset + k] = (case, k)
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
            # Breakpoints at every instance's entry; the hits are numbered per instance in
            # the order they happen, whatever the order of the arguments.
            for entry in plan:
                remote.point(0, entry, True)
            calls = dict.fromkeys(plan, -1)  # index of the last call entered, per instance
            left = sum(len(p) for p in plan.values())
            while left:
                remote.resume("c", "continue to controller_step")
                entry = remote.pc()
                if entry not in plan:
                    raise Failure(f"stopped at {entry:#x}, not at a breakpoint")
                calls[entry] += 1
                remote.step()  # off the breakpoint
                if calls[entry] + 1 not in plan[entry]:
                    continue
                # From call j's entry the next reading ends call j; the one after it starts
                # call j + 1. Count the following calls while they are wanted.
                end = remote.next_reading()
                while calls[entry] + 1 in plan[entry]:
                    remote.step()  # the reading that ends call j
                    remote.next_reading()
                    between, call = count_bracket(remote, entry, end)
                    calls[entry] += 1
                    case, k = plan[entry][calls[entry]]
                    print(f"G {case} {k} {between} {call}", flush=True)
                    left -= 1
                if calls[entry] >= max(plan[entry]):  # no more wanted: run its calls freely
                    remote.point(0, entry, False)
        finally:
            qemu.kill()
            qemu.communicate()


def main(argv):
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
        count(argv[1], wanted)
    except (Failure, subprocess.CalledProcessError, OSError) as e:
        sys.stderr.write(f"gdbcount: {e}\n")
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
