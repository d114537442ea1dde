use ecr_macros::ecr_method;

ecr_method!(r = 3, family = gauss);

fn main() {}
