"""mnacore.machine: the CPU a record names (model and vector extension, not only the
architecture: fits repeat on one CPU, not across CPUs)."""
from __future__ import annotations

import os
import platform

from mnacore.machine import cpu_name, cpu_summary

X86 = """processor\t: 0
vendor_id\t: GenuineIntel
model name\t: Intel(R) Xeon(R) Platinum 8480+
flags\t\t: fpu vme sse sse2 avx avx2 avx512f avx512bw amx_tile

processor\t: 1
model name\t: Intel(R) Xeon(R) Platinum 8480+
flags\t\t: fpu vme sse sse2 avx
"""
OLD_X86 = "model name\t: AMD Opteron(tm) Processor 6272\nflags\t\t: fpu sse sse2 avx\n"
ARM = "processor\t: 0\nBogoMIPS\t: 50.00\nFeatures\t: fp asimd evtstrm aes\nCPU implementer\t: 0x41\n"


def test_cpu_name_reads_the_model_and_the_widest_vector_extension(tmp_path):
    f = tmp_path / "cpuinfo"
    f.write_text(X86)
    # the first processor's flags: AVX-512 named though AVX2 and AVX are there too
    assert cpu_name(f) == "Intel(R) Xeon(R) Platinum 8480+, AVX-512"
    f.write_text(OLD_X86)
    assert cpu_name(f) == "AMD Opteron(tm) Processor 6272, AVX"
    # an ARM board lists no model name: the architecture stands in, with its vector unit
    f.write_text(ARM)
    assert cpu_name(f) == f"{platform.processor() or platform.machine()}, NEON"


def test_cpu_name_without_proc_falls_back_to_the_architecture(tmp_path):
    assert cpu_name(tmp_path / "missing") == (platform.processor() or platform.machine())


def test_cpu_summary_names_the_cores():
    assert cpu_summary() == f"{cpu_name()}, {os.cpu_count()} cores"
