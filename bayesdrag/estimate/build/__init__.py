"""What every estimation problem is built from: the start from the data (``start``,
``native_start``, ``gcv_spline``), knots and smoothing (``basis``, ``smoothing``), how large a
model the track determines (``model_size``), launch priors (``launch``), the wind layers a fit
flies (``winds``) and declared systematic sources as nuisance parameters (``sources``). Below the
recipes (``scheme1/``, ``scheme2``) and used by the diagnosis and the planner too."""
