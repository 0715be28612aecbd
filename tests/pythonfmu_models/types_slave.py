"""types_slave: a PythonFMU (FMI 2.0 co-simulation) test model with Real, Integer, Boolean and String
inputs, outputs and parameters, to check that FMUs from a third-party exporter run under dse-runner.

After every step from t to t + h (the outputs are computed in do_step only, so until the first step
they hold their start values 0.0, 0, False and ""):
    real_out   = gain * real_in + (t + h)
    int_out    = int_in + offset + number of steps taken
    bool_out   = bool_in != invert            (invert defaults to True: bool_out = not bool_in)
    string_out = string_in + suffix           (suffix defaults to "!")
"""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real, String


class TypesSlave(Fmi2Slave):
    author = "dse-runner tests"
    description = "Test FMU: Real, Integer, Boolean and String inputs, outputs and parameters"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.real_in = 0.0
        self.int_in = 0
        self.bool_in = False
        self.string_in = ""
        self.gain = 2.0
        self.offset = 0
        self.invert = True
        self.suffix = "!"
        self.real_out = 0.0
        self.int_out = 0
        self.bool_out = False
        self.string_out = ""
        self.steps = 0
        kinds = {"real": Real, "int": Integer, "bool": Boolean, "string": String}
        for prefix, kind in kinds.items():
            self.register_variable(
                kind(f"{prefix}_in", causality=Fmi2Causality.input, variability=Fmi2Variability.discrete)
            )
        for name, kind in [("gain", Real), ("offset", Integer), ("invert", Boolean), ("suffix", String)]:
            self.register_variable(
                kind(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
            )
        for prefix, kind in kinds.items():
            # initial="exact": the outputs start at their declared values (no initial-unknown to compute)
            self.register_variable(
                kind(
                    f"{prefix}_out",
                    causality=Fmi2Causality.output,
                    variability=Fmi2Variability.discrete,
                    initial=Fmi2Initial.exact,
                )
            )

    def do_step(self, current_time, step_size):
        self.steps += 1
        self.real_out = self.gain * self.real_in + current_time + step_size
        self.int_out = self.int_in + self.offset + self.steps
        self.bool_out = self.bool_in != self.invert
        self.string_out = self.string_in + self.suffix
        return True
