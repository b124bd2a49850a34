"""Tasks stage: MPPI reaching with a 7-DoF arm (:mod:`.arm`) and quadruped base driving (:mod:`.base`)."""
