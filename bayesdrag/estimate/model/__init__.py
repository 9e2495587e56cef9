"""The output-error problem and its maximum-likelihood fit: the problem's definition
(:mod:`~bayesdrag.estimate.model.problem`), the Gauss-Newton/Levenberg-Marquardt optimiser and
Cramér-Rao bounds (:mod:`~bayesdrag.estimate.model.ml`), colored (AR(1)) residuals
(:mod:`~bayesdrag.estimate.model.colored`), the noise read off a track
(:mod:`~bayesdrag.estimate.model.noise`) and one-sided outliers as a contamination of the noise
(:mod:`~bayesdrag.estimate.model.contamination`)."""
