"""Parameters and corrections estimated from data or images: moving targets, platform motion
(DPCA), autofocus. The top stage: it may import scene/, synthesis/ and image/, none of which
imports it."""
