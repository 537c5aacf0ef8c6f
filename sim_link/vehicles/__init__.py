"""Fake autopilots: one vehicle (:mod:`.vehicle`, with its mission protocol, commands, telemetry
and flight), a fleet of them on UDP (:mod:`.fleet`), link faults (:mod:`.faults`), and the
companion-computer emulator for real autopilots (:mod:`.companion`). Each behaviour that differs
between ArduPilot and PX4 is one field of :class:`.flavour.Flavour`, measured on SITL."""
