"""The golden vectors on Cortex-M4F, M3 and M0 under QEMU (make firmware-cores), and the
call-graph stack walk of a linked image."""

from __future__ import annotations

import pytest

from fogsf.bindings.cores import main
from fogsf.bindings.firmware import arm_tools_missing
from fogsf.bindings.stack import parse_image, walk

LISTING = """
00000100 <leaf>:
 100:	push	{r4, r5, lr}
 102:	vpush	{d8-d9}
 106:	sub	sp, #16
 108:	pop	{r4, r5, pc}

00000110 <mid>:
 110:	stmdb	sp!, {r4, r5, r6, r7, r8, lr}
 114:	sub.w	sp, sp, #264	@ 0x108
 118:	bl	100 <leaf>
 11c:	b.n	118 <mid+0x8>
 11e:	b.w	140 <__aeabi_fmul>

00000140 <__aeabi_fmul>:
 140:	push	{r4, lr}
 142:	bx	lr

00000150 <top>:
 150:	push	{lr}
 152:	bl	110 <mid>
 156:	bl	160 <loop>

00000160 <loop>:
 160:	push	{r3, lr}
 162:	bl	160 <loop>
"""


def test_the_walk_sums_frames_along_the_deepest_path() -> None:
    funcs = parse_image(LISTING)
    assert funcs["leaf"].frame == 12 + 16 + 16  # three registers, two d registers, 16
    assert funcs["mid"].frame == 24 + 264 and funcs["mid"].calls == {"leaf", "__aeabi_fmul"}
    bound = walk(funcs, ("mid",))
    assert bound.bytes == 24 + 264 + 44 and bound.path == ["mid", "leaf"]
    assert not bound.unbounded
    rec = walk(funcs, ("top",))
    assert "loop" in rec.unbounded  # recursion has no bound


@pytest.mark.skipif(arm_tools_missing() is not None, reason=f"{arm_tools_missing()}")
def test_make_firmware_cores_passes_on_every_core(tmp_path, capsys) -> None:
    assert main(["tests/fixtures/small_model", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    for label in ("Cortex-M4F (FPv4-SP hard float) under qemu-system-arm -M mps2-an386: PASS",
                  "Cortex-M3 (soft float) under qemu-system-arm -M mps2-an385: PASS",
                  "Cortex-M0 (soft float) under qemu-system-arm -M microbit: PASS"):
        assert label in out, out
    assert out.count("PASS: 12000 outputs bit-exact") == 6, out  # default and even time
    assert "build: even-time (-DFOGSF_EVEN_TIME=1)" in out, out
    assert "__aeabi_" in out  # the M0's deepest chain runs into libgcc's soft float


@pytest.mark.skipif(arm_tools_missing() is not None, reason=f"{arm_tools_missing()}")
def test_a_contracted_m4f_build_fails_its_golden_vectors(tmp_path, monkeypatch, capsys) -> None:
    """The check can fail: the M4F image built with -ffp-contract=fast (VFMA emitted; gcc in
    ISO C mode contracts only when told)."""
    import fogsf.bindings.firmware as fw
    monkeypatch.setattr(fw, "STRICT", tuple("-ffp-contract=fast" if f == "-ffp-contract=off"
                                            else f for f in fw.STRICT))
    assert main(["tests/fixtures/small_model", "--out", str(tmp_path),
                 "--cores", "cortex-m4f", "--builds", "default"]) == 1
    out = capsys.readouterr().out
    assert "FAIL" in out and "mismatch" in out, out
