"""The libFuzzer harness (make fuzz): it builds with clang -fsanitize=fuzzer,address,undefined,
the committed regression corpus passes, and a short fuzzing run finds nothing."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from fogsf.bindings.fuzz import CORPUS, build_fuzzer, regression, run_fuzzer

pytestmark = pytest.mark.skipif(shutil.which("clang") is None, reason="clang not installed")


def _libfuzzer_works(tmp_path) -> bool:
    src = tmp_path / "probe.c"
    src.write_text("#include <stddef.h>\n#include <stdint.h>\nint LLVMFuzzerTestOneInput("
                   "const uint8_t *d, size_t n);\nint LLVMFuzzerTestOneInput(const uint8_t *d, "
                   "size_t n) { (void)d; (void)n; return 0; }\n")
    return subprocess.run(["clang", "-fsanitize=fuzzer", str(src), "-o",
                           str(tmp_path / "probe")], capture_output=True).returncode == 0


@pytest.fixture(scope="module")
def fuzzer(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz")
    if not _libfuzzer_works(root):
        pytest.skip("clang has no libFuzzer runtime")
    return build_fuzzer(root / "build"), root


@pytest.mark.slow
def test_regression_corpus_passes_and_covers_every_mode(fuzzer) -> None:
    exe, _ = fuzzer
    modes = {p.read_bytes()[0] % 4 for p in CORPUS.iterdir()}
    assert modes == {0, 1, 2, 3}
    rc, text, steps = regression(exe)
    assert rc == 0, text[-3000:]
    assert steps > 0 and "runtime error" not in text


def test_short_fuzz_run_finds_nothing(fuzzer) -> None:
    exe, root = fuzzer
    work = root / "corpus"
    work.mkdir(exist_ok=True)
    rc, text, steps = run_fuzzer(exe, ["-seed=7", "-runs=400", "-max_len=4096",
                                       f"-artifact_prefix={root}/", str(work), str(CORPUS)],
                                 timeout=300)
    assert rc == 0, text[-3000:]
    assert steps >= 400, text[-1000:]


@pytest.mark.slow
def test_the_harness_reports_a_totality_violation(fuzzer, tmp_path) -> None:
    """The check can fail: an input that makes the harness see a bad output must crash.
    A model with decimation 0 is invalid; the harness demands corrected == 0 and only
    MODEL_INVALID for it, which the kernel gives: so run the harness built against a kernel
    whose invalid-model branch is broken (corrected = 1, never 0) and expect an abort."""
    exe, root = fuzzer
    from fogsf.bindings.fuzz import FUZZ_DIR, FUZZ_FLAGS, FUZZ_MAX
    from fogsf.bindings.kernel import C_DIR, STRICT
    broken = tmp_path / "fogsf.c"
    text = (C_DIR / "fogsf.c").read_text()
    needle = "    out->corrected_dps = 0.0f;\n    out->sf_ppm = 0.0f;"  # refuse()
    assert text.count(needle) == 1
    broken.write_text(text.replace(needle, "    out->corrected_dps = 1.0f;\n"
                                           "    out->sf_ppm = 0.0f;"))
    bad_exe = tmp_path / "fuzz_broken"
    subprocess.run(["clang", *STRICT, *FUZZ_FLAGS, *FUZZ_MAX, "-I", str(exe.parent), "-I",
                    str(C_DIR), str(FUZZ_DIR / "fuzz_step.c"), str(broken),
                    str(C_DIR / "fogsf_cell.c"), str(exe.parent / "fuzz_model.c"), "-o",
                    str(bad_exe)], check=True, capture_output=True)
    rc, out, _ = run_fuzzer(bad_exe, [str(CORPUS / "invalid_model")])
    assert rc != 0 and "invalid model must give 0" in out, out[-2000:]


@pytest.mark.slow
def test_the_even_time_build_passes_the_corpus_and_a_short_run(fuzzer) -> None:
    """The harness against the kernel built with FOGSF_EVEN_TIME (the spread step): the
    regression corpus and a short run, no finding."""
    _, root = fuzzer
    exe = build_fuzzer(root / "even", even_time=True)
    rc, text, steps = regression(exe)
    assert rc == 0 and steps > 0, text[-3000:]
    work = root / "corpus_even"
    work.mkdir(exist_ok=True)
    rc, text, steps = run_fuzzer(exe, ["-seed=11", "-runs=400", "-max_len=4096",
                                       f"-artifact_prefix={root}/", str(work), str(CORPUS)],
                                 timeout=300)
    assert rc == 0 and steps >= 400, text[-3000:]
