"""Impact-oscillator simulator (paper eqs 11-12) with pluggable physical effects."""
