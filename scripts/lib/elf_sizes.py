"""Prints `text data bss` of a 32-bit little-endian ELF (a Cortex-M firmware), as `size` counts
them, from its section headers: the allocated sections, NOBITS as bss, writable as data, the
rest as text. Used by scripts/cortex-m.sh (when no size tool is installed) and scripts/pil.sh.

    python3 scripts/lib/elf_sizes.py FIRMWARE.elf
"""
import struct
import sys

b = open(sys.argv[1], "rb").read()
shoff, = struct.unpack_from("<I", b, 0x20)
shentsize, shnum = struct.unpack_from("<HH", b, 0x2E)
t = d = s = 0
for i in range(shnum):
    _, typ, flags, _, _, size = struct.unpack_from("<IIIIII", b, shoff + i * shentsize)
    if flags & 2:  # SHF_ALLOC
        if typ == 8:  # SHT_NOBITS
            s += size
        elif flags & 1:  # SHF_WRITE
            d += size
        else:
            t += size
print(t, d, s)
