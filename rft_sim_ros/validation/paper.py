"""The RFT-SiM paper's figures that the validation compares against (Brown, Treers, Daltorio,
"Simulating Robotic Locomotion in Sand: Resistive Force Theory in an Open-Source Physics
Engine"; code github.com/Crab-Lab-CWRU/RFT-SiM; docs/references.md). SI units. Only numbers the text states; the
paper's plots are not digitised.
"""

#: Peak servo torque that sand adds to the rotating intruder, simulated, at every speed, N m.
TORQUE_INCREASE_SIM_NM = 0.055

#: Open C carriage progress relative to the flat intruder (fraction): simulated, experiment.
OPEN_C_VS_FLAT_SIM = -0.25
OPEN_C_VS_FLAT_EXPERIMENT = -0.53

#: Articulated leg: carriage travel per step, m: simulated, experiment.
LEG_STEP_SIM_M = 0.126
LEG_STEP_EXPERIMENT_M = 0.138

#: Hexapod mass without payload, kg; payloads, kg.
HEXAPOD_MASS_KG = 4.04
PAYLOADS_KG = (0.0, 1.0, 2.277)

#: Hexapod walking speed in experiment without payload, m/s. Not printed as a number: the
#: paper's low-friction model matched it "within 1.2 mm/s (1.85 %)", so 1.2e-3 / 0.0185.
HEXAPOD_SPEED_EXPERIMENT_MPS = 1.2e-3 / 0.0185

#: The paper's simulation underestimated the distance per step by this range (fraction).
HEXAPOD_STEP_UNDERESTIMATE = (0.096, 0.34)

#: Backward motion per cycle over forward motion in the paper's simulated example.
HEXAPOD_BACKWARD_FRACTION_SIM = 0.23

#: zeta (N/cm^3) at which the paper's simulated sinkage matched experiment; at zeta 3.75 the
#: simulated sinkage was 20 % above experiment.
SINKAGE_MATCH_ZETA = (5.67, 5.88)
SINKAGE_OVERESTIMATE_AT_3_75 = 0.20
