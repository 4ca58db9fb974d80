"""qdots files: saved boards (`qdots.io.checkpoint`, ``.npz``), experiment files
(`qdots.io.experiment_file`, TOML) and trajectories (`qdots.io.trajectory`, GSD for OVITO and freud)."""
