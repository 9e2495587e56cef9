"""The output-error problem and its maximum-likelihood fit: the problem's definition
(:mod:`~bayesdrag.estimate.model.problem`), the Gauss-Newton/Levenberg-Marquardt optimiser and
Cramér-Rao bounds (:mod:`~bayesdrag.estimate.model.ml`), colored (AR(1)) residuals
(:mod:`~bayesdrag.estimate.model.colored`) and the noise read off a track
(:mod:`~bayesdrag.estimate.model.noise`)."""
