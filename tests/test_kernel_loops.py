"""bench/kernel_loops.py: the innermost product loops read from a disassembly."""
import importlib.util
import sys
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "bench" / "kernel_loops.py"
_spec = importlib.util.spec_from_file_location("kernel_loops", _PATH)
kernel_loops = importlib.util.module_from_spec(_spec)
sys.modules["kernel_loops"] = kernel_loops
_spec.loader.exec_module(kernel_loops)

DISASSEMBLY = """
0000000000001000 <(anonymous namespace)::backward<(anonymous namespace)::Fp32Panels>(int)>:
    1000:	xor    %edi,%edi
    1004:	vmovaps (%r11,%rdx,1),%ymm2
    1008:	vfmadd231ps %ymm0,%ymm2,%ymm11
    100c:	vfmadd213ps 0x160(%rsp),%ymm1,%ymm0
    1010:	vmovaps %ymm0,0x160(%rsp)
    1014:	vmulps %ymm3,%ymm4,%ymm5
    1018:	jl     1004 <(anonymous namespace)::backward<(anonymous namespace)::Fp32Panels>(int)+0x4>
    101c:	vaddps %ymm1,%ymm2,%ymm3
    1020:	jmp    1000 <(anonymous namespace)::backward<(anonymous namespace)::Fp32Panels>(int)>

0000000000002000 <(anonymous namespace)::weight_gradient_columns(float const*)>:
    2000:	vbroadcastss (%rax),%ymm1
    2004:	vfmadd231ps (%rbx),%ymm1,%ymm2
    2008:	add    $0x4,%rax
    200c:	jne    2000 <(anonymous namespace)::weight_gradient_columns(float const*)>
    2010:	vaddps %ymm1,%ymm2,%ymm3
    2014:	jne    2010 <(anonymous namespace)::weight_gradient_columns(float const*)+0x10>

0000000000002800 <void (anonymous namespace)::Bf16Panels::product<6, true>((anonymous namespace)::Bf16Panels::Rows const&, int, int, float __vector(16) (*) [4]) const>:
    2800:	vdpbf16ps %zmm0,%zmm2,%zmm11
    2804:	jne    2800 <void (anonymous namespace)::Bf16Panels::product<6, true>((anonymous namespace)::Bf16Panels::Rows const&, int, int, float __vector(16) (*) [4]) const>

0000000000003000 <(anonymous namespace)::ForwardOp<float>::Compute()>:
    3000:	vfmadd231ps %ymm0,%ymm2,%ymm11
    3004:	jne    3000 <(anonymous namespace)::ForwardOp<float>::Compute()>
"""


def test_only_innermost_loops_of_product_functions_that_multiply_are_listed():
    """A product compiled out of line (``Bf16Panels::product``, not inlined into the ops) is a
    product function too."""
    loops = kernel_loops.innermost_loops(DISASSEMBLY)
    assert [(loop.function, loop.start) for loop in loops] == [
        ("backward<Fp32Panels>", 0x1004), ("weight_gradient_columns", 0x2000),
        ("Bf16Panels::product<6, true>", 0x2800)]


def test_a_loop_counts_its_products_vector_memory_and_stack_operands():
    spilled, clean, _ = kernel_loops.innermost_loops(DISASSEMBLY)
    assert (len(spilled.instructions), spilled.products, len(spilled.vector_memory),
            spilled.stack) == (6, 3, 3, 2)
    assert (clean.products, len(clean.vector_memory), clean.stack) == (1, 2, 0)


@pytest.mark.parametrize("target", ["", "foo bar", "../x"])
def test_a_target_that_is_no_march_name_is_refused_naming_the_option(capsys, target):
    """Before anything is built or printed: one line naming --march and the value (an empty
    value built native under the label '', a bad one was blamed on RNN_SEG_MARCH)."""
    with pytest.raises(SystemExit) as exit_:
        kernel_loops.main(["--march", "native", target])
    out, err = capsys.readouterr()
    assert exit_.value.code == 2 and out == ""
    assert f"--march {target!r}: not a GCC -march target name" in err


def test_a_compiler_that_cannot_run_is_named_in_one_line(tmp_path, monkeypatch):
    monkeypatch.setenv("CXX", str(tmp_path / "no-such-g++"))
    monkeypatch.delenv("RNN_SEG_MARCH", raising=False)     # build sets it: restored after
    with pytest.raises(RuntimeError, match=r"no-such-g\+\+: cannot run the compiler \(No such "):
        kernel_loops.build("haswell", tmp_path)
