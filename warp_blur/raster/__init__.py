"""The host side of the raster core: screen-tile binning and the device tables kernels read."""
