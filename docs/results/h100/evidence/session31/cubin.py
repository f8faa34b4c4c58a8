"""Compile Warp's unrolled projectile kernel (float32, 180 steps, hard contact) to an sm_90 cubin
with Warp's own NVRTC, no GPU needed, and print each function's registers (EIATTR_REGCOUNT) and
stack frame. usage: python cubin.py [PROJECTILE_PY]  (default: backends/warp/projectile.py;
e.g. `git show 6f9b10f:backends/warp/projectile.py > /tmp/old.py` for the build before the shared
step). For the instructions: nvdisasm -c OUT.cubin (the nvidia-cuda-nvdisasm wheel has it)."""
import importlib.util
import struct
import sys
import tempfile
from pathlib import Path

import warp as wp
from warp._src import build, context

wp.config.quiet = True
wp.init()
src = sys.argv[1] if len(sys.argv) > 1 else "backends/warp/projectile.py"
spec = importlib.util.spec_from_file_location("backends.warp._cubin_probe", src)
mod = importlib.util.module_from_spec(spec)
sys.modules[spec.name] = mod
spec.loader.exec_module(mod)
kernel = mod._unrolled(wp.float32, 180, "hard")
tmp = Path(tempfile.mkdtemp())
(tmp / "k.cu").write_text(context.ModuleBuilder(kernel.module, dict(kernel.module.options), target="cuda").codegen("cuda"))
build.build_cuda(str(tmp / "k.cu"), 90, str(tmp / "k.cubin"), pch_dir=str(tmp), use_precompiled_headers=False)
b = (tmp / "k.cubin").read_bytes()
shoff, = struct.unpack_from("<Q", b, 0x28)
shentsize, shnum, shstrndx = struct.unpack_from("<HHH", b, 0x3A)
heads = [struct.unpack_from("<IIQQQQIIQQ", b, shoff + i * shentsize) for i in range(shnum)]
names = heads[shstrndx][4]
symtab = next(h for h in heads if h[1] == 2)            # SHT_SYMTAB: function names by index
strtab = heads[symtab[6]][4]
def sym(i):
    o, = struct.unpack_from("<I", b, symtab[4] + i * 24)
    return b[strtab + o:b.index(b"\0", strtab + o)].decode()
for h in heads:
    if b[names + h[0]:b.index(b"\0", names + h[0])] != b".nv.info":
        continue
    i, end = h[4], h[4] + h[5]
    while i < end:      # (format, attribute, size, value): 0x2f REGCOUNT, 0x11 FRAME_SIZE
        fmt, attr = b[i], b[i + 1]
        size = struct.unpack_from("<H", b, i + 2)[0] if fmt == 4 else 0
        if fmt == 4 and attr in (0x2F, 0x11):
            f, v = struct.unpack_from("<II", b, i + 4)
            print(sym(f).split("_cuda_kernel_")[-1], "registers" if attr == 0x2F else "stack bytes", v)
        i += 4 + size
print("cubin:", tmp / "k.cubin")
