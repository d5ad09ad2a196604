"""What is simulated: the scenario (sonar, platform, schedule) and the papers' presets."""

from .scenario import (
                       Array,
                       Medium,
                       Platform,
                       PulseSchedule,
                       Recording,
                       SamplingWarning,
                       Scenario,
                       Sonobuoy,
                       Waveform,
)

__all__ = ["Array", "Medium", "PulseSchedule", "Platform", "Recording", "SamplingWarning", "Scenario",
           "Sonobuoy", "Waveform"]
