"""Device code (@wp.func / @wp.kernel only): kernel structs, ray tests, light tables, texture and shadow lookups, shading, the sharp and shadow-map rasterizers."""

from ..core.struct_refs import install

install()   # before any kernel module below is defined: their struct arguments pass by reference
