"""The fused loops' innermost product loops as the compiler wrote them, for any target.

Builds ``rnn_seg/kernels/lstm_loops.cc`` with the project's compile command for each ``--march``
target (GCC ``-march`` names; the library is never loaded, so this processor need not have the
target's instructions: the AVX-512 build can be read on an AVX2 machine), disassembles it with
``objdump`` and lists, per product function (the forward and backward ops' per panel products,
inlined in them or out of line as ``Panels::product<rows, backward>``, the weight gradient's
micro-kernel), each innermost loop that multiplies: its instructions, products (``vfmadd``,
``vdpbf16ps``; ``mulps`` where the target has no FMA), vector memory operands, and those
addressed from the stack or frame pointer (``%rsp`` / ``%rbp``: spills, vectors that did not
stay in registers; an ``%rbp`` used as a plain register would count too). A product's loop
should have none on AVX2 and AVX-512 targets; the generic build (no AVX: a vector spans two SSE
registers) spills. The long loops with few products are the gates' activations, not the
products.

This reads code, it does not time it: ``lstm_sweep.py`` and ``sweep_phases.py`` do, on a
processor that runs the target.

    python bench/kernel_loops.py --march native skylake-avx512 sapphirerapids haswell x86-64
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

FUNCTION = re.compile(r"^[0-9a-f]+ <(.*)>:$")
INSTRUCTION = re.compile(r"^\s+([0-9a-f]+):\s+(.*)$")
JUMP = re.compile(r"^j\w+\s+([0-9a-f]+)\b")
#: The product functions, by the part of their demangled name that says which.
PRODUCTS = re.compile(r"((?:forward|backward)<\(anonymous namespace\)::\w+>"
                      r"|\w+Panels::product<\d+, (?:true|false)>"
                      r"|weight_gradient_\w+)")
#: Instructions that multiply (and add): FMA and BF16 dot products, or a multiply where the
#: target has no FMA.
PRODUCT = ("vfmadd", "vfnmadd", "vdpbf16ps", "vmulps", "mulps")
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
STACK = ("(%rsp", "(%rbp")


@dataclass(frozen=True)
class Loop:
    """One innermost loop: where it starts and what its instructions are."""

    function: str
    start: int
    instructions: tuple[str, ...]

    @property
    def products(self) -> int:
        return sum(i.startswith(PRODUCT) for i in self.instructions)

    @property
    def vector_memory(self) -> list[str]:
        return [i for i in self.instructions if "(" in i and "mm" in i]

    @property
    def stack(self) -> int:
        return sum(any(s in i for s in STACK) for i in self.vector_memory)


def build(target: str, out: Path) -> Path:
    """The library built for ``target`` (``RNN_SEG_MARCH``) at ``out``; the compiler's last
    lines on failure."""
    from rnn_seg.kernels import build as kernels

    os.environ[kernels.MARCH_ENV] = target
    library = out / f"lstm_loops-{target}.so"
    command = kernels.compile_command(kernels.SOURCE, library)
    try:
        done = subprocess.run(command, capture_output=True, text=True)
    except OSError as e:
        raise RuntimeError(f"{command[0]}: cannot run the compiler ({e.strerror}; $CXX names "
                           "it, g++ when unset)") from None
    if done.returncode:
        raise RuntimeError(f"-march={target}: the build failed:\n" + done.stderr[-2000:])
    return library


def disassemble(library: Path) -> str:
    """``objdump -d -C --no-show-raw-insn`` of ``library``."""
    return subprocess.run(["objdump", "-d", "-C", "--no-show-raw-insn", str(library)],
                          capture_output=True, text=True, check=True).stdout


def innermost_loops(disassembly: str) -> list[Loop]:
    """Each product function's innermost loops (a backward jump's range holding no other) that
    multiply, from ``objdump -d -C --no-show-raw-insn`` output."""
    loops = []
    for name, body in _functions(disassembly):
        product = PRODUCTS.search(name)
        if not product:
            continue
        at = [(int(a, 16), text) for a, text in body]
        edges = [(int(m.group(1), 16), a) for a, text in at
                 if (m := JUMP.match(text)) and int(m.group(1), 16) <= a]
        for start, end in edges:
            if any((s, e) != (start, end) and start <= s and e <= end for s, e in edges):
                continue
            loop = Loop(product.group(1).replace("(anonymous namespace)::", ""), start,
                        tuple(text for a, text in at if start <= a <= end))
            if loop.products:
                loops.append(loop)
    return loops


def _functions(disassembly: str) -> list[tuple[str, list[tuple[str, str]]]]:
    """``(demangled name, [(address, instruction)])`` per function of the disassembly."""
    out: list[tuple[str, list[tuple[str, str]]]] = []
    for line in disassembly.splitlines():
        if m := FUNCTION.match(line):
            out.append((m.group(1), []))
        elif out and (m := INSTRUCTION.match(line)):
            out[-1][1].append((m.group(1), m.group(2)))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--march", nargs="+", default=["native"], metavar="TARGET",
                        help="GCC -march targets to build for (default: native)")
    args = parser.parse_args(argv)
    from jigsaws_tools.cli.common import import_tensorflow

    import_tensorflow()                 # its start-up lines filtered out, as the commands do
    from rnn_seg.kernels.build import MARCH_NAME

    for target in args.march:
        if not MARCH_NAME.fullmatch(target):
            parser.error(f"--march {target!r}: not a GCC -march target name (e.g. native, "
                         "haswell, skylake-avx512)")
    if shutil.which("objdump") is None:
        print("error: objdump (binutils) is needed to read the library", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as folder:
        try:           # every target built and read before the table: an error comes alone
            found = {target: innermost_loops(disassemble(build(target, Path(folder))))
                     for target in args.march}
        except RuntimeError as e:
            print(f"error: {e}", file=sys.stderr)
            return 1
    print(f"{'target':<16} {'function':<24} {'loop at':>8} {'instr':>6} {'prods':>6} "
          f"{'vec mem':>8} {'stack':>6}")
    for target, loops in found.items():
        if not loops:
            print(f"{target:<16} (no loop of a product function multiplies)")
        for loop in loops:
            print(f"{target:<16} {loop.function:<24} {loop.start:>8x} "
                  f"{len(loop.instructions):>6} {loop.products:>6} "
                  f"{len(loop.vector_memory):>8} {loop.stack:>6}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
