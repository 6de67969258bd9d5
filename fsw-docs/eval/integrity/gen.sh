#!/bin/bash
# Assemble fsw-docs/eval/integrity.md from the eval outputs.
out=$1
python3 - "$out" <<'PY'
import sys,csv,subprocess
out=sys.argv[1]
head=open('fsw-docs/eval/integrity/head.md').read()
def margins(paths):
    rows=[]
    for p in paths:
        try: rows+=[r for r in csv.DictReader(open(p)) if r['success']=='true' and r.get('spread_m') and float(r['final_t_mm'])<=100 and float(r['final_r_deg'])<=1.5 and r.get('wrong_place')!='1.0000']
        except FileNotFoundError: pass
    f=lambda k:[float(r[k]) for r in rows]
    return rows,f
suites=[('paper',4),('baseline',2),('uncertainty50',2),('stepsize',1),('wrongplace',2)]
import os
suites=[x for x in suites if os.path.exists(f'/tmp/integ/after-{x[0]}-t{x[1]}/table.md')]
paths=[f'/tmp/integ/after-{s}-t{n}/trials.csv' for s,n in suites]
rows,f=margins(paths)
if rows:
    head=head.replace('MARGIN_PRIOR','largest distance %.3f m, %.2f° (%d correct successes)'%(max(f('prior_dt_m')),max(f('prior_dr_deg')),len(rows)))
    head=head.replace('MARGIN_SPREAD','smallest %.3f m'%min(f('spread_m')))
    head=head.replace('MARGIN_REPROJ','largest %.2f px'%max(f('reproj_px')))
GATES=("RELOC_POSE_OUTSIDE_PRIOR","RELOC_INLIERS_DEGENERATE","RELOC_RESIDUAL_HIGH")
def cw(r,ok):
    return ok and (float(r['final_t_mm'])>100 or float(r['final_r_deg'])>1.5 or r.get('wrong_place')=='1.0000')
summ=['## Summary\n','| suite (test profile) | trials | successes without gates | confident wrong without gates | successes with gates | confident wrong with gates |','|---|---:|---:|---:|---:|---:|']
for s,n in suites:
    p=f'/tmp/integ/after-{s}-t{n}/trials.csv'
    try: rr=list(csv.DictReader(open(p)))
    except FileNotFoundError: continue
    b=[r for r in rr if r['success']=='true' or r['failure'] in GATES]
    a=[r for r in rr if r['success']=='true']
    summ.append(f"| {s} ({n} per group) | {len(rr)} | {len(b)} | {sum(cw(r,True) for r in b)} | {len(a)} | {sum(cw(r,True) for r in a)} |")
lost=0
for s_,n_ in suites:
    for r in csv.DictReader(open(f'/tmp/integ/after-{s_}-t{n_}/trials.csv')):
        if r['failure'] in GATES and not cw(r,True): lost+=1
summ.append(f"\nCorrect successes lost to the gates (a gated trial that was not confident wrong): {lost}.")
# Before / after the first-fix rule (VTSM-RELOC-036): the same suites and seeds
# run by the binary before it, where that run exists.
cmp=['\n### Before and after `RELOC_NO_CONSENSUS` (same suites and seeds)\n\nOutcome = success, failure code and final error. The times are not a comparison of the rule except on `wrongplace`: the before runs used one thread under a heavier load; every other suite ran the same search.\n',
     '| suite (test profile) | trials | successes before | successes after | confident wrong before | confident wrong after | trials with another outcome | mean time per trial before (s) | after (s) |',
     '|---|---:|---:|---:|---:|---:|---:|---:|---:|']
for s_,n_ in suites:
    try: bb=list(csv.DictReader(open(f'/tmp/integ/before-{s_}-t{n_}/trials.csv')))
    except FileNotFoundError:
        cmp.append(f'| {s_} ({n_} per group) | — | not run before | | | | | | |'); continue
    aa=list(csv.DictReader(open(f'/tmp/integ/after-{s_}-t{n_}/trials.csv')))
    key=lambda r:(r['group'],r['trial'])
    bm={key(r):r for r in bb}
    changed=sum(1 for r in aa if key(r) in bm and (bm[key(r)]['success'],bm[key(r)]['failure'],bm[key(r)]['final_t_mm'])!=(r['success'],r['failure'],r['final_t_mm']))
    ok=lambda rr:[r for r in rr if r['success']=='true']
    mt=lambda rr:sum(float(r['time_s']) for r in rr)/max(1,len(rr))
    cmp.append(f"| {s_} ({n_} per group) | {len(aa)} | {len(ok(bb))} | {len(ok(aa))} | {sum(cw(r,True) for r in ok(bb))} | {sum(cw(r,True) for r in ok(aa))} | {changed} | {mt(bb):.2f} | {mt(aa):.2f} |")
summ+=cmp
head=head+'\n'.join(summ)+'\n\n'
body=['## `vtsm eval` suites, test profile (480×320)\n',
'Each block is the integrity table printed at the end of `table.md` by the command above it, pasted verbatim; binary `cargo build --release -p vtsm-sim` at @REV@, 2 rayon threads on a 2-core machine shared with other builds (load average @LOAD@, from `uptime`; times are not comparable between rows). The \"before\" runs of the comparison above are the same commands with the binary of 81dd7ed (one thread).\n']
for s,n in suites:
    p=f'/tmp/integ/after-{s}-t{n}/table.md'
    try: t=open(p).read()
    except FileNotFoundError:
        body.append(f'### {s}\n\nNot run in this revision (time).\n'); continue
    i=t.index('\nIntegrity:')
    body.append(f'### {s}\n\n```sh\nvtsm eval --suite {s} --profile test --trials {n} --quiet --out /tmp/integ/after-{s}-t{n}\n```\n'+t[i:]+'\n')
import os as _o
txt=head+'\n'.join(body)+open('fsw-docs/eval/integrity/tail.md').read()
txt=txt.replace('@REV@',_o.environ.get('REV','?')).replace('@LOAD@',_o.environ.get('LOAD','?'))
open(out,'w').write(txt)
PY
