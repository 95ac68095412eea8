MODULE Door_GOLDEN_1
  ! doorloc hinge targets for door GOLDEN-1: 2 hinge(s), 19 targets, cell frame, mm
  ! pose x=1.25 z=-3.5 yaw=0.8 deg face_y=0
  ! tool diameter 16 mm, spindle 18000 rpm, feed 25 mm/s
  PERS tooldata tSpindle:=[TRUE,[[0,0,250],[0.7071068,0.7071068,0,0]],[12,[0,0,120],[1,0,0,0],0,0,0]];
  PERS wobjdata wobjDoorCell:=[FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  CONST speeddata vMill:=[25,500,5000,1000];
  CONST robtarget H1_APP:=[[22.64532,-10,254.8239],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H1_P1:=[[22.64532,3.5,254.8239],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H1_P2:=[[29.64464,3.5,254.9216],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H1_P3:=[[28.47182,3.5,338.9135],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H1_P4:=[[14.47318,3.5,338.718],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H1_P5:=[[15.646,3.5,254.7262],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H1_P6:=[[22.64532,3.5,254.8239],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H1_RET:=[[22.64532,-10,254.8239],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_APP:=[[-1.297658,-10,1754.636],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P1:=[[-1.299054,3.22,1754.736],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P2:=[[6.700027,3.22,1754.857],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P3:=[[8.671768,3.22,1756.895],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P4:=[[7.415032,3.22,1846.896],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P5:=[[5.387163,3.22,1848.878],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P6:=[[-2.612197,3.22,1848.777],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P7:=[[-4.584217,3.22,1846.759],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P8:=[[-3.32776,3.22,1756.778],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_P9:=[[-1.300171,3.22,1754.816],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget H2_RET:=[[-1.300171,-10,1754.816],[0.9999756,0,-0.00698126,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

  PROC MillHinges()
    ! start the spindle (18000 rpm) before calling; cell-specific I/O
    ConfL\Off;
    MoveL H1_APP,v200,z5,tSpindle\WObj:=wobjDoorCell;
    MoveL H1_P1,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H1_P2,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H1_P3,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H1_P4,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H1_P5,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H1_P6,vMill,z0,tSpindle\WObj:=wobjDoorCell;
    MoveL H1_RET,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_APP,v200,z5,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P1,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P2,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P3,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P4,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P5,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P6,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P7,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P8,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_P9,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    MoveL H2_RET,vMill,fine,tSpindle\WObj:=wobjDoorCell;
    ConfL\On;
  ENDPROC
ENDMODULE
