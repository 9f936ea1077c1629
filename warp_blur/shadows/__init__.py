"""Shadow maps in motion: lights' faces and samples, maps rendered, shared or warped over the shutter."""
