#!/usr/bin/env python3
"""Lists the functions longer than LIMIT lines in the given folders (issue 35's goal: none over
about 150 in src/, cuda/ and tools/). A heuristic: a definition is a line ending in "{" after a
parameter list, its body the lines to the matching brace (comments and strings skipped).

  python3 scripts/long_functions.py 150 src cuda tools
"""
import re, sys, pathlib
limit = int(sys.argv[1]); roots = sys.argv[2:]
sig = re.compile(r'^\s*(?:template\s*<.*>\s*)?(?:[\w:<>,\*&~\s]+?\s+)?[\w:~<>]+\s*\([^;]*\)\s*(?:const|noexcept|override|\s)*(?:->\s*[\w:<>]+\s*)?\{\s*(//.*)?$')
for root in roots:
  for p in sorted(pathlib.Path(root).rglob('*')):
    if p.suffix not in ('.cpp','.hpp','.cu','.cuh','.h'): continue
    lines = p.read_text().split('\n')
    i = 0
    while i < len(lines):
      l = lines[i]
      # allow multi-line signatures: join up to 6 lines
      m = None
      for k in range(1,7):
        chunk = ' '.join(x.strip() for x in lines[i:i+k])
        if chunk.endswith('{') or re.search(r'\{\s*(//.*)?$', chunk):
          if sig.match(chunk) and not re.match(r'^\s*(if|for|while|switch|else|do|return|namespace|struct|class|enum)\b', chunk) and '=' not in chunk.split('(')[0]:
            m = k
          break
        if ';' in lines[i+k-1] if i+k-1 < len(lines) else True: break
      if m:
        depth = 0; j = i
        started = False
        while j < len(lines):
          s = re.sub(r'//.*', '', lines[j]); s = re.sub(r'"(\\.|[^"\\])*"', '""', s); s = re.sub(r"'(\\.|[^'\\])'", "''", s)
          depth += s.count('{') - s.count('}')
          if '{' in s: started = True
          if started and depth <= 0: break
          j += 1
        n = j - i + 1
        if n > limit: print(f"{n:5d} {p}:{i+1}: {lines[i].strip()[:90]}")
        i = j + 1 if n > 3 and not lines[i].startswith(('namespace')) else i + 1
      else:
        i += 1
