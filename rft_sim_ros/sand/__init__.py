"""The sand engine: plates from MuJoCo geoms, the compiled RFT coupling and the step."""
