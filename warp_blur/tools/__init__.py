"""What users run: the CLI, frame ranges on workers or a cluster, info, the precision report, native stderr filtering."""
