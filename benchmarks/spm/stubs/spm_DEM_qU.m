function spm_DEM_qU(varargin)
% No-op stand-in for SPM's plot of the conditional moments (headless reference runs).
end
