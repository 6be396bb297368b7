"""Control of the PMSM drive under uncertainty ([Thesis], thesis §4.3-4.4).

* :mod:`.pi` - PI control in the d-q frame (eqs. 4.27-4.39);
* :mod:`.cautious` - cautious control (eqs. 4.50-4.65, approximation 4.57) and certainty
  equivalence control (§4.3.3);
* :mod:`.loss` - tracking loss (eq. 4.16), reference trajectory (§4.4.1) and the failure
  definition;
* :mod:`.smc` - the thesis SMC: the reduced PMSM model's optimal proposal + the generic guided
  filter, and the point estimates (mean / random sample / maximum) used for control;
* :mod:`.closed_loop` - closed-loop simulation: true plant + estimator (the SMC or the EKF) +
  controller, batched and run in parallel processes.
"""
from .loss import (FailureCriterion, estimation_failed, reference_speed, tracking_loss)
from .pi import PIGains, pi_dq_control, pi_update
from .cautious import cautious_control, cc_constants

__all__ = ["FailureCriterion", "estimation_failed", "reference_speed", "tracking_loss",
           "PIGains", "pi_dq_control", "pi_update", "cautious_control", "cc_constants"]
