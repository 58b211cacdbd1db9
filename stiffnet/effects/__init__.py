"""Library of physical effects the base impact oscillator lacks (see ``base``)."""
