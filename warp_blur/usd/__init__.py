"""Reading USD into NumPy: the stage (camera, resolution, shutter, frames), the framing camera, geometry, materials, lights, primvars, textures."""
