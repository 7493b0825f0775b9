"""The EdgeDoG trainer: EdgeGaussians' schedule plus the DoG kernel and the dual uncertainty."""
