function ok = ft_harness(problem, path, check)
  % flowtrack exercise harness (Octave): reads a vectors file, calls your function, prints the outputs.
  %
  %   ft_harness(PROBLEM, 'cases.json', false)  prints  OUTPUT <case id> <json of the outputs>  per case
  %   ft_harness(PROBLEM, 'public.json', true)  also compares with each case's "expected" and prints
  %                                             CASE <problem> <id> PASS|FAIL <err> <message>
  % The file is in the course's shared vectors format. Do not edit (the grader uses its own copy).
  doc = jsondecode(fileread(path), 'makeValidName', false);
  cases = doc.cases;
  if isstruct(cases)
    cases = num2cell(cases);
  end
  ok = true;
  for k = 1:numel(cases)
    c = cases{k};
    try
      out = ft_solve(problem, c.input);
    catch err
      printf('ERROR %s %s\n', c.id, strrep(err.message, sprintf('\n'), ' '));
      ok = false;
      continue;
    end
    names = fieldnames(out);
    parts = cell(1, numel(names));
    for i = 1:numel(names)
      parts{i} = sprintf('"%s": %s', names{i}, ft_json(out.(names{i})));
    end
    printf('OUTPUT %s {%s}\n', c.id, strjoin(parts, ', '));
    if check
      [pass, worst, msg] = ft_compare(out, c.expected, c.rtol, c.atol);
      ok = ok && pass;
      verdict = 'FAIL';
      if pass
        verdict = 'PASS';
      end
      printf('CASE %s %s %s %.3g %s\n', problem, c.id, verdict, worst, msg);
    end
  end
end

function out = ft_solve(problem, in)
  switch problem
    case 'cv_model'
      [F, Q] = cv_model(in.dt, in.q);
      out = struct('F', {ft_mat(F)}, 'Q', {ft_mat(Q)});
    case 'kalman_step'
      [x, P] = kalman_step(in.x(:), in.P, in.F, in.Q, in.H, in.R, in.z(:));
      out = struct('x', {x(:)'}, 'P', {ft_mat(P)});
    case 'projection_jacobian'
      J = projection_jacobian(in.X(:), in.fx, in.fy, in.cx, in.cy);
      out = struct('J', {ft_mat(J)});
    case 'mahalanobis_gating'
      m = numel(in.z_pred);
      Z = reshape(in.Z, [], m);
      [d2, inside] = mahalanobis_gating(in.z_pred(:), in.S, Z, in.gate);
      out = struct('d2', {double(d2(:))'}, 'inside', {double(inside(:))'});
    case 'assignment'
      C = in.C;
      if size(C, 1) > size(C, 2)
        error('C must have at least as many columns as rows');
      end
      a = assignment(C);
      out = struct('assignment', {double(a(:))' - 1});  % the shared format counts from 0
    otherwise
      error('unknown problem %s', problem);
  end
end

function m = ft_mat(m)
  m = {double(m)};  % a cell: the JSON writer keeps it a matrix even when it has one row
end

function s = ft_json(v)
  if iscell(v)
    M = v{1};
    rows = cell(1, rows_of(M));
    for i = 1:rows_of(M)
      rows{i} = ft_json(M(i, :));
    end
    s = ['[' strjoin(rows, ', ') ']'];
  else
    items = arrayfun(@(x) ft_num(x), double(v(:))', 'UniformOutput', false);
    s = ['[' strjoin(items, ', ') ']'];
  end
end

function n = rows_of(M)
  n = size(M, 1);
end

function s = ft_num(x)
  if isnan(x)
    s = 'NaN';
  elseif isinf(x)
    s = ifelse_str(x > 0, 'Infinity', '-Infinity');
  else
    s = sprintf('%.17g', x);
  end
end

function s = ifelse_str(c, a, b)
  if c
    s = a;
  else
    s = b;
  end
end

function [pass, worst, msg] = ft_compare(out, expected, rtol, atol)
  pass = true; worst = 0; msg = 'ok';
  names = fieldnames(expected);
  for i = 1:numel(names)
    e = expected.(names{i});
    if ~isfield(out, names{i})
      pass = false; msg = [names{i} ' missing']; continue;
    end
    g = out.(names{i});
    if iscell(g)
      g = g{1};
    end
    if numel(g) ~= numel(e) || (ismatrix(e) && min(size(e)) > 1 && ~isequal(size(g), size(e)))
      pass = false; msg = sprintf('%s: size %s, expected %s', names{i}, mat2str(size(g)), mat2str(size(e)));
      continue;
    end
    err = abs(g(:) - e(:));
    worst = max([worst; err]);
    bad = find(~(err <= atol + rtol * abs(e(:))), 1);
    if ~isempty(bad) && pass
      pass = false; msg = sprintf('%s(%d): got %.17g, expected %.17g', names{i}, bad, g(bad), e(bad));
    end
  end
end
