#!/usr/bin/env python3
# Groups a perf profile of an mlclust run into stages (BENCHMARKS.md, issue 13):
#   perf report -i perf.data --no-children --sort dso,symbol --percent-limit 0 \
#     | grep % > syms.txt; /usr/bin/python3 bench/perf_stages.py syms.txt
import re,collections,sys
cats=[
 ('engine (ML: merges, EMLO, guard, heap)',r'MeshSpace|MultilevelEngine|ConnectivityGuard|RunMultilevel|Partition<|OdeHeap|tbb|ComputeAllOdes|Emlo|Optimi|std::vector|std::deque'),
 ('prepare (validate, adjacency, face measures)',r'Validate|Adjacency|FaceMeasures|PrepareDraco|PreparedMesh|BuildFace|MeshProblem'),
 ('draco encode',r'draco.*Encod|Encode.*Draco|draco::.*Encoder'),
 ('draco decode',r'draco'),
 ('read OFF',r'ReadMesh|ReadOff|Tokens|ParseUnsigned|ParseDouble|strto|from_chars|fast_float'),
 ('protobuf (serialize, parse)',r'protobuf|google::'),
 ('gRPC',r'grpc|gpr_|event_engine|libgrpc'),
 ('sink + client rebuild (HierarchyLog)',r'HierarchyLog|LevelSink|Assembler|client::|StepLabels|LabelsAt|ResultStore|server::'),
 ('write outputs',r'Write|ofstream|ostream'),
 ('malloc/memcpy (libc)',r'libc\.so'),
 ('dynamic loader (start-up)',r'ld-linux|_dl_|do_lookup'),
 ('kernel (page faults, threads, sockets)',r'\[k\]'),
]
tot=collections.Counter(); other=[]
for line in open(sys.argv[1]):
    m=re.match(r'\s*([\d.]+)%\s+(\S+)\s+(.*)',line)
    if not m: continue
    p=float(m.group(1)); rest=m.group(2)+' '+m.group(3)
    for c,rx in cats:
        if re.search(rx,rest): tot[c]+=p; break
    else: tot['other']+=p; other.append((p,rest[:100]))
for c,v in tot.most_common(): print(f'| {c} | {v:.1f}% |')
for p,r in sorted(other,reverse=True)[:5]: print('   other',p,r)
