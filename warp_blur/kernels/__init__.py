"""Device code (@wp.func / @wp.kernel only): kernel structs, ray tests, light tables, texture and shadow lookups, shading, the sharp and shadow-map rasterizers."""
