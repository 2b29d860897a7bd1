function f = fcnchk(f, varargin)
% Stand-in for MATLAB's fcnchk (removed from Octave 7): a function handle is returned as it is,
% a function name becomes its handle, any other string an anonymous function of the named
% arguments (default x). SPM's model checks call it on M(i).f and M(i).g.
if isa(f, 'function_handle') || isa(f, 'inline')
    return
end
if ~ischar(f)
    error('fcnchk: expected a function handle or a string');
end
names = varargin(cellfun(@ischar, varargin));
names = names(~strcmp(names, 'vectorized'));
if any(exist(f) == [2 3 5])   %#ok<EXIST> a file, MEX or built-in function
    f = str2func(f);
    return
end
if isempty(names), names = {'x'}; end
f = str2func(['@(' strjoin(names, ',') ') ' f]);
end
